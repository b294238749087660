//! Real measured data (HSR-RobotCali, RobotCali IRB 120), read at run time from ../shared/data
//! and never committed. A test whose files are absent says SKIP and passes.

use std::path::{Path, PathBuf};
use twincal::calib::fit::floor::FloorKind;
use twincal::calib::fit::noise_model::NoiseChoice;
use twincal::calib::fit::robust::step_offset_mm;
use twincal::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec};
use twincal::dataset::{Dataset, Split};
use twincal::diagnose::{diagnose, DiagnoseOptions};

/// A real data file under ../shared/data.
fn shared(rel: &str) -> Option<PathBuf> {
    crate::datasets::shared(&format!("data/{rel}"))
}

fn condition_identifiable(r: &CalibResult) -> f64 {
    r.solve.identifiability["condition_identifiable"].as_f64().unwrap()
}

/// The unknown arm: every 5th row of the pool held out (the rows interleave with the training
/// rows, as unseen rows of the same robot do). Over three search seeds the fit converges, holds
/// the joint that does not move, stays well conditioned, and predicts the held-out rows near the
/// data's floor (repeatability and angle resolution) without the worst 1 %.
#[test]
fn hsr_generic_model_converges_and_predicts_interleaved_rows_near_the_floor() {
    let Some(path) = shared("hsr-robotcali/hsr_robotcali_pool.csv") else { return };
    let mut ds = Dataset::load(&path).unwrap();
    for (i, r) in ds.rows.iter_mut().enumerate() {
        r.split = Some(if i % 5 == 4 { Split::Test } else { Split::Train });
    }
    let mut ratios = Vec::new();
    let mut first = None;
    for seed in 0..3 {
        let mut o = CalibOptions::new(ModelSpec::Generic, Method::LM);
        o.seed = seed;
        let r = calibrate(&ds, None, &o).unwrap();
        assert!(r.solve.converged, "seed {seed}: {}", r.solve.stop_reason);
        assert_eq!(r.solve.identifiability["still_joints"], serde_json::json!([6]), "seed {seed}");
        assert!(condition_identifiable(&r) < 1e7, "seed {seed}: condition {}", condition_identifiable(&r));
        let floor = r.evaluation.noise_floor.as_ref().unwrap();
        assert!(floor.has(FloorKind::Repeatability) && floor.has(FloorKind::AngleResolution), "{floor:?}");
        let trimmed = r.evaluation.metrics.test_after_trimmed.unwrap().rmse;
        eprintln!("seed {seed}: held-out RMSE without the worst 1 % {trimmed:.4} mm, floor {:.4} mm, {} iterations", floor.total_mm, r.solve.iterations);
        ratios.push(trimmed / floor.total_mm);
        first.get_or_insert(r);
    }
    // The target, on every seed (a scipy least-squares fit of the same data from the
    // same kind of starts reaches 1.13 on this split).
    assert!(ratios.iter().all(|r| *r <= 1.15), "held-out / floor over seeds 0..3: {ratios:?}");
    lands_in_the_same_basin_on_80_percent_of_the_rows(&ds, &first.unwrap());
}

/// The papers' IRB 120: Levenberg–Marquardt converges, the stretch of the acquisition whose
/// readings slipped (data rows ~114–176, 3.7 then 6.2 then 8.2 mm short) is found as reading
/// steps and corrected, the floor names the 0.1° angle logging, every test row is predicted
/// better than the papers' LM (about 1.2 mm) and the rows that are not outliers by the training
/// rows' rule to well under a millimetre, on three random 80/20 splits of rows (as the papers
/// split).
#[test]
fn robotcali_lm_converges_and_names_the_disturbed_stretch() {
    let Some(path) = shared("robotcali-irb120/robotcali_pool.csv") else { return };
    let ds = Dataset::load(&path).unwrap();
    for seed in 0..3 {
        let mut o = CalibOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap(), Method::LM);
        o.split.test_fraction = Some(0.2);
        // The papers' protocol (random rows), against their LM figure; held-out whole sweeps are
        // the next test's yardstick.
        o.split.by = twincal::calib::pipeline::SplitBy::Rows;
        o.seed = seed;
        let r = calibrate(&ds, None, &o).unwrap();
        assert!(r.solve.converged, "seed {seed}: {}", r.solve.stop_reason);
        // Rows ~114-176 read 3.7, then 6.2, then 8.2 mm short: three reading steps, corrected.
        let steps: Vec<_> = r.screen.reading_steps.iter().filter(|s| s.first_row >= 100 && s.last_row <= 190).collect();
        assert!(steps.len() >= 2 && steps.iter().all(|s| s.offset_mm < -3.0), "seed {seed}: {:?}", r.screen.reading_steps);
        let (lo, hi) = steps.iter().fold((f64::MAX, f64::MIN), |(a, b), s| (a.min(s.offset_mm), b.max(s.offset_mm)));
        assert!(hi - lo > 3.0, "seed {seed}: the offsets of a slipping reading grow: {steps:?}");
        let angle = r.evaluation.noise_floor.as_ref().unwrap().part(FloorKind::AngleResolution);
        assert!((0.2..0.35).contains(&angle), "seed {seed}: angle-resolution floor {angle}");
        let inliers = r.evaluation.metrics.test_after_inliers.unwrap();
        let all = r.evaluation.metrics.test_after.unwrap();
        eprintln!("seed {seed}: test RMSE {:.3} mm on every row, {:.3} mm on the {} inliers", all.rmse, inliers.rmse, inliers.n);
        assert!(inliers.rmse < 0.75 && inliers.n >= 140, "seed {seed}: {inliers:?}");
        // The papers report LM at about 1.2 mm on this robot.
        assert!(all.rmse < 1.2, "seed {seed}: every test row {all:?}");
    }
}

/// The twin with what real data bring (`scenarios/irb120_realistic.toml`: 0.1° angle logging,
/// sweeps over a narrow range, three runs of readings that jumped by an offset): LM converges,
/// the runs are found as reading steps where the truth put them, with their offsets, and nothing
/// else is kept out, the floor names the angle
/// logging, the rows that are not outliers are predicted at that floor, and the identifiable
/// parameters agree with their truth-equivalent values; the papers' methods and the generic
/// model run on the same data and converge.
#[test]
fn the_realistic_twin_scenario_names_its_glitches_and_reaches_its_floor() {
    use twincal::sim::generate::{generate, Silent};
    use twincal::sim::scenario::Scenario;
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/irb120_realistic.toml");
    let s = Scenario::from_toml(&std::fs::read_to_string(&path).unwrap(), "irb120_realistic").unwrap();
    let robot = s.load_robot(Some(path.parent().unwrap())).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let g = generate(&s, &robot, &Silent).unwrap();
    twincal::sim::generate::write_outputs(&g, dir.path()).unwrap();
    let glitches = &g.truth.glitch_rows;
    assert_eq!(glitches.len(), 24);
    let ds = Dataset::load(dir.path()).unwrap();
    let truth = twincal::calib::pipeline::TruthFile::find(dir.path()).unwrap();
    let lm =
        calibrate(&ds, truth.as_ref(), &CalibOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap(), Method::LM))
            .unwrap();
    assert!(lm.solve.converged, "{}", lm.solve.stop_reason);
    // Random rows as the test set and rows taken as independent: the test rows share their
    // sweeps' rounding with training rows, the held-out RMSE falls below the floor, and the
    // result says the split leaks (the default, the file's own split with the noise model, not).
    let leaks = |r: &CalibResult| r.warnings.iter().any(|w| w.contains("the split leaks"));
    assert!(!leaks(&lm), "{:?}", lm.warnings);
    let rows = CalibOptions {
        split: twincal::calib::pipeline::SplitOptions { test_fraction: Some(0.25), by: twincal::calib::pipeline::SplitBy::Rows },
        floor: twincal::calib::pipeline::FloorOptions { noise_model: NoiseChoice::Off, ..Default::default() },
        ..CalibOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap(), Method::LM)
    };
    let independent = calibrate(&ds, None, &rows).unwrap();
    let floor = independent.evaluation.noise_floor.as_ref().unwrap().total_mm;
    eprintln!("random rows, rows independent: test inliers {:.4} mm, floor {floor:.4} mm", independent.evaluation.metrics.test_after_inliers.unwrap().rmse);
    assert!(leaks(&independent), "{:?}", independent.warnings);
    // The glitch runs are one offset each: found as reading steps where the truth put them, with
    // the offset the truth gives (the median of measured minus true length over the run).
    assert_eq!(lm.screen.reading_steps.len(), 3, "{:?} (outlier runs {:?})", lm.screen.reading_steps, lm.screen.outlier_runs);
    let tr = truth.as_ref().unwrap();
    for st in &lm.screen.reading_steps {
        let rows: Vec<usize> = (st.first_row - 1..st.last_row).collect();
        assert!(rows.len() >= 4 && rows.iter().all(|r| glitches.contains(r)), "step {st:?} is no glitch run");
        let mut off: Vec<f64> = rows.iter().map(|&r| ds.rows[r].l_mm().unwrap() - tr.poses[r].length_true_mm).collect();
        off.sort_by(f64::total_cmp);
        let want = off[off.len() / 2];
        // Rows of one sweep share the rounding of the joints that hold still: the step's offset
        // holds that common error too, at most a few times the angle-resolution floor.
        let angle = lm.evaluation.noise_floor.as_ref().unwrap().part(FloorKind::AngleResolution);
        assert!((st.offset_mm - want).abs() < 4.0 * st.std_mm + 2.0 * angle, "step {st:?}: the truth's offset is {want:.3} mm");
    }
    // A test row between a step's first (last) training row and the clean training row before
    // (after) it may be on either side of the jump: it takes the mean of both offsets and may
    // stand out; nothing else may.
    let at_edge = |row: usize| lm.screen.reading_steps.iter().any(|s| row + 3 >= s.first_row && row <= s.last_row + 3);
    for o in lm.screen.outliers.iter().chain(&lm.screen.test_outliers) {
        assert!(glitches.contains(&(o.row - 1)) || at_edge(o.row), "row {} is no glitch: {o:?}", o.row);
    }
    let floor = lm.evaluation.noise_floor.as_ref().unwrap();
    let angle = floor.sources.iter().find(|s| s.source == FloorKind::AngleResolution).unwrap();
    assert!((0.15..0.35).contains(&angle.rms_mm) && angle.detail.contains("0.1 deg"), "{angle:?}");
    // The test rows reach the floor: they share sweeps with the training rows (the scenario's own
    // split), but the noise model keeps the fit from learning the sweeps' rounding, so they are
    // predicted at the floor, not below it.
    let inliers = lm.evaluation.metrics.test_after_inliers.unwrap();
    assert!(inliers.rmse < 1.1 * floor.total_mm, "{inliers:?} vs floor {}", floor.total_mm);
    // Against the truth at the commanded angles (the logged ones are rounded), the fit with the
    // logging error as its noise model is near the truth within its uncertainties, and nearer
    // than the fit that takes rows as independent.
    let t = lm.evaluation.truth_comparison.as_ref().unwrap();
    assert!(t.within_3_sigma * 10 >= t.identifiable * 9 && t.max_abs_z < 6.0, "{t:?}");
    let independent = calibrate(
        &ds,
        truth.as_ref(),
        &CalibOptions {
            floor: twincal::calib::pipeline::FloorOptions { noise_model: NoiseChoice::Off, ..Default::default() },
            ..CalibOptions::new(ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap(), Method::LM)
        },
    )
    .unwrap();
    let u = independent.evaluation.truth_comparison.as_ref().unwrap();
    eprintln!(
        "truth comparison: noise model {}/{} within 3 sigma (max |z| {:.2}), rows independent {}/{} ({:.2})",
        t.within_3_sigma, t.identifiable, t.max_abs_z, u.within_3_sigma, u.identifiable, u.max_abs_z
    );
    assert!(t.within_3_sigma > u.within_3_sigma && t.max_abs_z < u.max_abs_z, "{t:?} against {u:?}");
    for (method, model) in [(Method::DSADE_GKAN, "irb120"), (Method::PSO_EKF_AWNN, "irb120"), (Method::LM, "generic6r")] {
        let spec = if model == "generic6r" { ModelSpec::Generic } else { ModelSpec::parse(model, twincal::calib::pipeline::Parametrisation::Hayati).unwrap() };
        let r = calibrate(&ds, None, &CalibOptions::new(spec, method)).unwrap();
        let e = r.evaluation.metrics.test_after_inliers.unwrap().rmse;
        eprintln!("{} / {model}: test inliers {e:.4} mm (LM {:.4})", method.name(), inliers.rmse);
        assert_eq!(r.screen.reading_steps.len(), 3, "{}: {:?}", method.name(), r.screen.reading_steps);
        assert!(e < 1.1 * floor.total_mm, "{} / {model}: {e} vs floor {}", method.name(), floor.total_mm);
    }
}

/// The generic model's search is robust to which rows it sees: refitted on 80 % of the training
/// rows (every fifth one dropped), it lands in the same basin — its predictions of the held-out
/// rows differ from the full fit's (`a`, search seed 0 on `ds`) by well under the data's floor.
/// Part of the interleaved-rows test above, which has the full fit already.
fn lands_in_the_same_basin_on_80_percent_of_the_rows(ds: &Dataset, a: &CalibResult) {
    let mut train_seen = 0;
    let fewer = Dataset {
        rows: ds
            .rows
            .iter()
            .filter(|r| {
                if r.split == Some(Split::Test) {
                    return true;
                }
                train_seen += 1;
                train_seen % 5 != 0
            })
            .cloned()
            .collect(),
        source: "80 % of the training rows".into(),
    };
    let b = calibrate(&fewer, None, &CalibOptions::new(ModelSpec::Generic, Method::LM)).unwrap();
    let test = Dataset { rows: ds.rows.iter().filter(|r| r.split == Some(Split::Test)).cloned().collect(), source: "held out".into() };
    let (pa, pb) = (a.predict_rows(&test), b.predict_rows(&test));
    let diff = (pa.iter().zip(&pb).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / pa.len() as f64).sqrt();
    let floor = a.evaluation.noise_floor.as_ref().unwrap().total_mm;
    eprintln!("RMS difference of the two fits' predictions {diff:.4} mm, floor {floor:.4} mm");
    assert!(diff < 0.5 * floor, "{diff} vs floor {floor}");
    let ratio = b.evaluation.metrics.test_after_trimmed.unwrap().rmse / floor;
    assert!(ratio <= 1.2, "80 % fit: {ratio}");
}

/// The laser-tracker grids of a UR5 (850 poses, `ur_description`'s URDF) and a Barrett WAM (216
/// poses, 7 joints, `urdf/wam.urdf`): LM on the geometry and the instrument placement, a fifth of
/// the rows held out (stratified, over three seeds). The held-out mean absolute position error
/// |Δp| falls well below the placed nominal arm's and below the published figure of a
/// calibration with a graph network (UR5 0.155 mm, WAM 2.92 mm, on the authors' 20 random poses:
/// another test set, so a comparison, not a replication).
#[test]
fn tracker_grids_of_a_ur5_and_a_wam_calibrate_below_the_published_error() {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let ur5_urdf = root.join("../shared/reference/ur_description/ur5_robot.urdf");
    // Against the nominal arm with its instrument placed (a rigid fit that already takes most of
    // the error away): the UR5 to under a quarter, the cable-driven WAM (repeatability 2 mm) to
    // under two thirds.
    for (rel, urdf, published, factor) in
        [("ur5-lasertracker/ur5_grid_pool.csv", ur5_urdf.clone(), 0.155, 0.25), ("wam-lasertracker/wam_grid.csv", root.join("urdf/wam.urdf"), 2.92, 0.67)]
    {
        let Some(path) = shared(rel) else { continue };
        if !urdf.exists() {
            crate::datasets::skip(&urdf);
            continue;
        }
        let ds = Dataset::load(&path).unwrap();
        let spec = ModelSpec::parse(urdf.to_str().unwrap(), twincal::calib::pipeline::Parametrisation::Hayati).unwrap();
        let mut after = Vec::new();
        for seed in 0..3 {
            let mut o = CalibOptions::new(spec.clone(), Method::LM);
            o.split.test_fraction = Some(0.2);
            o.seed = seed;
            let r = calibrate(&ds, None, &o).unwrap();
            let (b, a) = (r.evaluation.metrics.test_position_before.unwrap(), r.evaluation.metrics.test_position_after.unwrap());
            eprintln!("{rel} seed {seed}: held-out |dp| mean {:.4} mm (RMS {:.4}), before {:.4} mm", a.mae, a.rmse, b.mae);
            assert!(a.mae < factor * b.mae, "{rel} seed {seed}: {} vs {}", a.mae, b.mae);
            after.push(a.mae);
        }
        let worst = after.iter().copied().fold(0.0, f64::max);
        assert!(worst < published, "{rel}: held-out mean |dp| up to {worst:.4} mm against the published {published} mm");
    }
}

/// Issue 33's yardstick on every real file: trained on the rows outside a held-out quarter of
/// whole blocks (`--test-fraction 0.25`, split by blocks: rows of a held-out sweep never train),
/// the model `diagnose` exports predicts the held-out rows at least as well as plain `calibrate`
/// (LM) on the same training rows, outside glitch stretches (rows either model misses by more
/// than 8 median absolute residuals). One test per file, so that they run side by side.
fn diagnosed_model_on_held_out_blocks(rel: &str) {
    use twincal::calib::pipeline::{split_rows, SplitBy};
    use twincal::dataset::ReadOptions;
    use twincal::measurement::Measurement;
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    let reference = root.join("../shared/reference/ur_description");
    let (ur5, ur10, wam) = (reference.join("ur5_robot.urdf"), reference.join("ur10_robot.urdf"), root.join("urdf/wam.urdf"));
    let (urdf, measurement): (Option<&Path>, Option<Measurement>) = match rel {
        r if r.starts_with("ipa-ur10") => (Some(&ur10), Some(Measurement::Point)),
        r if r.starts_with("ur5") => (Some(&ur5), None),
        r if r.starts_with("wam") => (Some(&wam), None),
        _ => (None, None),
    };
    let Some(path) = shared(rel) else { return };
    let spec = match urdf {
        Some(u) if !u.exists() => {
            crate::datasets::skip(u);
            return;
        }
        Some(u) => ModelSpec::parse(u.to_str().unwrap(), twincal::calib::pipeline::Parametrisation::Hayati).unwrap(),
        None if rel.starts_with("hsr") => ModelSpec::Generic,
        None => ModelSpec::parse("irb120", twincal::calib::pipeline::Parametrisation::Hayati).unwrap(),
    };
    let load = ReadOptions { measurement, ..Default::default() };
    // Series a spans 100 h in a file not in time order: read sorted by t, its first session
    // (5 257 rows over 18 h, up to the first pause over 6 h; its three sessions are calibrated as
    // one campaign in stations.rs, and diagnosed forward in time in docs/real-data.md).
    let ds = if rel.ends_with("series_a.csv") {
        let sorted = twincal_cli::bench::real::sorted_by_column(&std::fs::read_to_string(&path).unwrap(), "t").unwrap();
        let mut d = Dataset::from_csv_reader_with(sorted.as_bytes(), rel, &load).unwrap();
        let t: Vec<f64> = d.rows.iter().map(|r| r.t_s.unwrap()).collect();
        let end = (1..t.len()).find(|&i| t[i] - t[i - 1] > 6.0 * 3600.0).unwrap_or(t.len());
        d.rows.truncate(end);
        assert_eq!(d.rows.len(), 5257);
        d
    } else {
        Dataset::load_with(&path, &load).unwrap()
    };
    let (train, test) = split_rows(&ds, &twincal::dataset::blocks::detect(&ds, None).0, Some(0.25), 0, SplitBy::Blocks).unwrap();
    let train_ds = Dataset { rows: train.iter().map(|&i| ds.rows[i].clone()).collect(), source: rel.into() };
    let calibrated = calibrate(&train_ds, None, &CalibOptions::new(spec.clone(), Method::LM)).unwrap();
    // Without the logging error's noise model (where the calibration used none, the same fit).
    let independent = if calibrated.solve.noise_model.is_some() {
        calibrate(
            &train_ds,
            None,
            &CalibOptions {
                floor: twincal::calib::pipeline::FloorOptions { noise_model: NoiseChoice::Off, ..Default::default() },
                ..CalibOptions::new(spec.clone(), Method::LM)
            },
        )
        .unwrap()
    } else {
        calibrated.clone()
    };
    let (d, diagnosed) = diagnose(&train_ds, &DiagnoseOptions::new(spec), &|_| {}).unwrap();
    // Every row predicted in acquisition order (backlash flanks follow it), the test rows judged.
    let residuals = |r: &CalibResult| -> Vec<Vec<f64>> {
        let p = r.predict_rows(&ds);
        let dim = p.len() / ds.rows.len();
        test.iter().map(|&i| ds.rows[i].values_mm().unwrap().iter().zip(&p[i * dim..(i + 1) * dim]).map(|(m, p)| m - p).collect()).collect()
    };
    let (a, b, c) = (residuals(&calibrated), residuals(&diagnosed), residuals(&independent));
    let mut flat: Vec<f64> = a.iter().flatten().map(|v| v.abs()).collect();
    flat.sort_by(f64::total_cmp);
    let limit = 8.0 * flat[flat.len() / 2];
    let keep: Vec<usize> = (0..test.len()).filter(|&k| a[k].iter().chain(&b[k]).chain(&c[k]).all(|v| v.abs() < limit)).collect();
    let rms = |m: &[Vec<f64>]| (keep.iter().flat_map(|&k| m[k].iter()).map(|v| v * v).sum::<f64>() / (keep.len() * m[0].len()) as f64).sqrt();
    let (ra, rb, rc) = (rms(&a), rms(&b), rms(&c));
    eprintln!(
        "{rel}: {} of {} held-out rows; calibrate {ra:.4} mm (noise model {}; {rc:.4} mm without, ratio {:.3}), diagnose ({}) {rb:.4} mm, ratio {:.3}",
        keep.len(),
        test.len(),
        if calibrated.solve.noise_model.is_some() { "on" } else { "not needed" },
        ra / rc,
        d.verdict,
        rb / ra
    );
    assert!(keep.len() * 10 >= test.len() * 8, "{rel}: {} of {} rows judged", keep.len(), test.len());
    // The logging error's noise model costs no accuracy on unseen blocks where it applies.
    assert!(ra <= 1.002 * rc, "{rel}: calibrate with the noise model predicts held-out blocks at {ra:.4} mm, without at {rc:.4} mm");
    // No worse, to 0.2 % (the generalised least squares of a geometric-only diagnosis may
    // move the last digit against LM's fit).
    assert!(rb <= 1.002 * ra, "{rel}: the diagnosed model ({}) predicts held-out blocks at {rb:.4} mm, plain calibrate at {ra:.4} mm", d.verdict);
    if rel.starts_with("robotcali") {
        robotcali_diagnosis_exports_the_model_it_reports(&train_ds, &train, &d, &diagnosed);
    }
}

/// `diagnose` on the papers' IRB 120 (its training rows `ds`, rows `train` of the file):
/// sweep-ordered rows make blocked folds extrapolate, so it judges on interleaved folds and
/// says so; it finds the reading steps of rows 100-190 of the file; every cause it names is
/// confirmed on rows selection never saw and is at least twice its uncertainty; and the model it
/// exports reproduces the in-sample RMSE the report prints. (Part of the held-out yardstick's
/// RobotCali test, which has diagnosed these rows already.)
fn robotcali_diagnosis_exports_the_model_it_reports(ds: &Dataset, train: &[usize], d: &twincal::diagnose::Diagnosis, result: &CalibResult) {
    assert_eq!(d.judged_on, "interleaved", "{}", d.judged_on_reason);
    assert!(d.baseline.heldout_rmse_blocked_mm > 1.5 * d.baseline.heldout_rmse_interleaved_mm);
    let in_file = |row: usize| train[row - 1] + 1;
    assert!(
        d.reading_steps.iter().filter(|s| in_file(s.first_row) >= 100 && in_file(s.last_row) <= 190 && s.offset_mm < -3.0).count() >= 2,
        "{:?}",
        d.reading_steps
    );
    for c in &d.causes {
        assert!(c.magnitude.abs() >= 2.0 * c.uncertainty, "{}", c.summary());
        assert!(c.confirmation_rmse_after_mm < c.confirmation_rmse_before_mm, "{}", c.summary());
    }
    assert!(d.noise_floor.has(FloorKind::AngleResolution), "{:?}", d.noise_floor);
    let predicted = result.predict_rows(ds);
    let out: Vec<usize> = d.outliers.iter().map(|o| o.row - 1).collect();
    let kept: Vec<f64> =
        (0..ds.rows.len()).filter(|i| !out.contains(i)).map(|i| ds.rows[i].l_mm().unwrap() - step_offset_mm(&d.reading_steps, i) - predicted[i]).collect();
    let rmse = (kept.iter().map(|v| v * v).sum::<f64>() / kept.len() as f64).sqrt();
    assert!((rmse - d.final_train_rmse_mm).abs() < 1e-6 * rmse, "exported model {rmse} vs report {}", d.final_train_rmse_mm);
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_robotcali() {
    diagnosed_model_on_held_out_blocks("robotcali-irb120/robotcali_pool.csv");
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_hsr() {
    diagnosed_model_on_held_out_blocks("hsr-robotcali/hsr_robotcali_pool.csv");
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_ur10_series_a() {
    diagnosed_model_on_held_out_blocks("ipa-ur10/ur10_series_a.csv");
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_ur10_series_b() {
    diagnosed_model_on_held_out_blocks("ipa-ur10/ur10_series_b.csv");
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_ur10_series_d() {
    diagnosed_model_on_held_out_blocks("ipa-ur10/ur10_series_d.csv");
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_ur5() {
    diagnosed_model_on_held_out_blocks("ur5-lasertracker/ur5_grid_pool.csv");
}

#[test]
fn the_diagnosed_model_predicts_held_out_blocks_no_worse_than_calibrate_wam() {
    diagnosed_model_on_held_out_blocks("wam-lasertracker/wam_grid.csv");
}
