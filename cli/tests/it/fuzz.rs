//! Property tests (a fuzz harness in the suite) for the readers of files a user may have edited
//! by hand: the result-file loader (`CalibResult::load`, then `predict` on what it accepted),
//! the `ik --targets` reader (`dataset::read_csv_columns`), the pose-list, `compensate
//! --targets` and dataset readers (the data `iso9283` reads), the scenario loader (then a short
//! generation of what it accepted) and the shard parts `reduce` joins. Whatever the bytes, they
//! answer with a value or an error: never a panic.

use proptest::prelude::*;
use serde_json::Value;
use std::path::Path;
use std::sync::OnceLock;
use twincal::calib::effects::EffectKind;
use twincal::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec};
use twincal::dataset::Dataset;
use twincal::sim::generate::{generate, Silent};
use twincal::sim::scenario::Scenario;

/// Result files of real calibrations (LM with effect blocks and a torque model; the RBF
/// corrector), as JSON, and the data they were fitted on.
fn fixtures() -> &'static (Vec<Value>, Dataset) {
    static F: OnceLock<(Vec<Value>, Dataset)> = OnceLock::new();
    F.get_or_init(|| {
        let (s, robot) = Scenario::default_embedded().unwrap();
        let data = generate(&s, &robot, &Silent).unwrap().dataset;
        let spec = ModelSpec::nominal(robot, twincal::calib::pipeline::Parametrisation::Hayati);
        let mut lm = CalibOptions::new(spec.clone(), Method::LM);
        lm.effects = vec![(EffectKind::Compliance, Some(1)), (EffectKind::Backlash, Some(2)), (EffectKind::Thermal, None)];
        let results = [calibrate(&data, None, &lm).unwrap(), calibrate(&data, None, &CalibOptions::new(spec, Method::RBF)).unwrap()];
        (results.iter().map(|r| serde_json::to_value(r).unwrap()).collect(), data)
    })
}

/// Every leaf of `v` as a JSON pointer.
fn leaves(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(m) if !m.is_empty() => m.iter().for_each(|(k, c)| leaves(c, format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")), out)),
        Value::Array(a) if !a.is_empty() => a.iter().enumerate().for_each(|(i, c)| leaves(c, format!("{at}/{i}"), out)),
        _ => out.push(at),
    }
}

/// Values a hand edit leaves behind, weighted towards numbers out of range.
fn replacement() -> impl Strategy<Value = Value> {
    prop_oneof![
        4 => prop_oneof![Just(1e308), Just(-1e308), Just(1e12), Just(-1.0), Just(0.0), Just(-0.0), Just(7.0), Just(1e-300), Just(3.5)].prop_map(|v| serde_json::json!(v)),
        2 => prop_oneof![Just(-1i64), Just(0), Just(6), Just(7), Just(99), Just(i64::MAX), Just(i64::MIN)].prop_map(|v| serde_json::json!(v)),
        1 => any::<f64>().prop_filter("JSON numbers are finite", |v| v.is_finite()).prop_map(|v| serde_json::json!(v)),
        1 => Just(Value::Null),
        1 => Just(serde_json::json!("x")),
        1 => Just(serde_json::json!([])),
        1 => Just(serde_json::json!({})),
        1 => Just(serde_json::json!(true)),
    ]
}

/// Loads `bytes` as a result file and, when that succeeds, predicts the fixture's first rows:
/// both must return (a panic fails the property).
fn load_and_predict(bytes: &[u8], data: &Dataset, dir: &Path) -> Result<(), String> {
    let path = dir.join("result.json");
    std::fs::write(&path, bytes).unwrap();
    let rows = Dataset { rows: data.rows[..20].to_vec(), source: "first rows".into() };
    std::panic::catch_unwind(|| {
        if let Ok(r) = CalibResult::load(&path) {
            if r.require_columns(&rows).is_ok() && r.require_measurement(&rows).is_ok() && r.model.chain.n_joints == rows.n_joints() {
                let _ = r.predict_rows(&rows);
            }
        }
    })
    .map_err(|e| e.downcast_ref::<String>().cloned().or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default())
}

/// The harness' base cases: the unedited files load and predict the rows they were fitted on
/// (so the properties below reach `predict`), and an effect block on a joint the arm lacks is
/// refused.
#[test]
fn the_fixtures_load_and_a_known_bad_edit_is_refused() {
    let (results, data) = fixtures();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("result.json");
    for v in results {
        std::fs::write(&path, serde_json::to_vec(v).unwrap()).unwrap();
        let r = CalibResult::load(&path).expect("an unedited result file loads");
        assert!(r.predict_rows(data).iter().all(|p| p.is_finite()));
    }
    let mut v = results[0].clone();
    *v.pointer_mut("/model/effects/0/joint").expect("an effect block with a joint") = serde_json::json!(99);
    std::fs::write(&path, serde_json::to_vec(&v).unwrap()).unwrap();
    assert!(CalibResult::load(&path).is_err());
}

/// The scenario property's base case: each unedited scenario loads and generates its first poses
/// (so the property reaches the generation).
#[test]
fn the_fuzzed_scenarios_load_and_generate_unedited() {
    let root = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    for file in ["irb120_evo_nph.toml", "irb120_tracker.toml", "ur10_pose.toml"] {
        let (mut s, robot) = Scenario::load(&root.join(file)).unwrap();
        s.sampling.poses = s.sampling.poses.min(6);
        s.sampling.test = s.sampling.test.min(1);
        assert_eq!(generate(&s, &robot, &Silent).unwrap().dataset.rows.len(), 6, "{file}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn an_edited_result_file_loads_or_is_refused(which in 0usize..2, edits in proptest::collection::vec((any::<prop::sample::Index>(), replacement()), 1..4)) {
        let (results, data) = fixtures();
        let mut v = results[which].clone();
        let mut paths = Vec::new();
        leaves(&v, String::new(), &mut paths);
        for (at, new) in &edits {
            if let Some(slot) = v.pointer_mut(&paths[at.index(paths.len())]) {
                *slot = new.clone();
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let outcome = load_and_predict(serde_json::to_string(&v).unwrap().as_bytes(), data, dir.path());
        prop_assert!(outcome.is_ok(), "panicked: {:?} after editing {:?}", outcome, edits.iter().map(|(i, n)| (paths[i.index(paths.len())].clone(), n.clone())).collect::<Vec<_>>());
    }

    #[test]
    fn a_truncated_or_spliced_result_file_is_refused_without_a_panic(which in 0usize..2, cut in any::<prop::sample::Index>(), junk in proptest::collection::vec(any::<u8>(), 0..16)) {
        let (results, data) = fixtures();
        let text = serde_json::to_vec(&results[which]).unwrap();
        let at = cut.index(text.len());
        let mut bytes = text[..at].to_vec();
        bytes.extend(&junk);
        let dir = tempfile::tempdir().unwrap();
        let outcome = load_and_predict(&bytes, data, dir.path());
        prop_assert!(outcome.is_ok(), "panicked: {:?}", outcome);
    }

    #[test]
    fn the_targets_reader_answers_any_text(
        lines in proptest::collection::vec(proptest::collection::vec(prop_oneof![
            3 => (-2000.0..2000.0f64).prop_map(|v| v.to_string()),
            1 => Just(String::new()), 1 => Just("NaN".to_string()), 1 => Just("inf".to_string()),
            1 => Just("1,5".to_string()), 1 => Just("\"4\"".to_string()), 1 => "[a-z#;\"]{1,4}",
        ], 0..6), 0..8),
        header in prop_oneof![Just("x,y,z"), Just("\u{feff}X_mm;y_mm;Z"), Just("\"x\",\"y\",\"z\",extra"), Just("x\ty\tz"), Just("a,b"), Just("")],
        sep in prop_oneof![Just(","), Just(";"), Just("\t")],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("targets.csv");
        let body: Vec<String> = lines.iter().map(|l| l.join(sep)).collect();
        std::fs::write(&path, format!("{header}\n{}\n", body.join("\n"))).unwrap();
        let outcome = std::panic::catch_unwind(|| twincal::dataset::read_csv_columns(&path, &["x", "y", "z"]).map(|rows| rows.len()));
        prop_assert!(outcome.is_ok(), "the reader panicked");
        if let Ok(Ok(n)) = outcome {
            prop_assert!(n <= lines.len());
        }
    }

    #[test]
    fn the_pose_list_targets_and_data_readers_answer_any_text(
        lines in proptest::collection::vec(proptest::collection::vec(prop_oneof![
            3 => (-200.0..200.0f64).prop_map(|v| v.to_string()),
            1 => (-3.0..3.0f64).prop_map(|v| v.to_string()),
            1 => Just(String::new()), 1 => Just("NaN".to_string()), 1 => Just("1e308".to_string()),
            1 => Just("1,5".to_string()), 1 => "[a-z#;\"]{1,4}",
        ], 0..9), 0..8),
        header in prop_oneof![
            Just("q1,q2,q3,q4,q5,q6"), Just("q1,q2,q3,q4,q5,q6,payload_kg"), Just("x,y,z,rx,ry,rz"), Just("q1,q2,q3,q4,q5,q6,x,y,z,rx,ry,rz"),
            Just("\u{feff}q1;q2;q3;q4;q5;q6;L"), Just("q1,q2,q3,q4,q5,q6,q7"), Just("x,y,z,rx,ry"), Just("")
        ],
        sep in prop_oneof![Just(","), Just(";")],
    ) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("rows.csv");
        let body: Vec<String> = lines.iter().map(|l| l.join(sep)).collect();
        std::fs::write(&path, format!("{header}\n{}\n", body.join("\n"))).unwrap();
        let robot = twincal::robot::Robot::irb120();
        let poses = std::panic::catch_unwind(|| twincal::sim::pose_list::read_pose_list(&path, &robot).map(|l| l.q));
        prop_assert!(poses.is_ok(), "the pose-list reader panicked");
        if let Ok(Ok(q)) = poses {
            let limits = robot.limits();
            prop_assert!(q.iter().all(|p| p.iter().zip(&limits).all(|(v, (lo, hi))| v.is_finite() && *v >= lo - 1e-9 && *v <= hi + 1e-9)), "a pose outside the limits: {q:?}");
        }
        let targets = std::panic::catch_unwind(|| twincal::compensate::read_targets(&path, 6, twincal::measurement::Euler::XYZ).map(|t| t.len()));
        prop_assert!(targets.is_ok(), "the targets reader panicked");
        let data = std::panic::catch_unwind(|| Dataset::load(&path).map(|d| d.rows.len()));
        prop_assert!(data.is_ok(), "the dataset reader panicked");
    }

    #[test]
    fn an_edited_scenario_loads_and_generates_or_is_refused(which in 0usize..3, edits in proptest::collection::vec((any::<prop::sample::Index>(), replacement()), 1..4)) {
        let root = std::path::PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
        let file = ["irb120_evo_nph.toml", "irb120_tracker.toml", "ur10_pose.toml"][which];
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        let mut v: Value = serde_json::to_value(toml::from_str::<toml::Value>(&text).unwrap()).unwrap();
        let mut paths = Vec::new();
        leaves(&v, String::new(), &mut paths);
        for (at, new) in &edits {
            if let Some(slot) = v.pointer_mut(&paths[at.index(paths.len())]) {
                *slot = new.clone();
            }
        }
        // TOML has no null: an edit to null removes the key.
        fn no_nulls(v: &mut Value) {
            match v {
                Value::Object(m) => { m.retain(|_, c| !c.is_null()); m.values_mut().for_each(no_nulls) }
                Value::Array(a) => { a.retain(|c| !c.is_null()); a.iter_mut().for_each(no_nulls) }
                _ => {}
            }
        }
        no_nulls(&mut v);
        let Ok(edited) = toml::to_string(&v) else { return Ok(()) };
        // The scenario in a folder of its own, its URDF where it names it (../urdf/).
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("s")).unwrap();
        std::fs::create_dir_all(dir.path().join("urdf")).unwrap();
        std::fs::copy(root.join("../urdf/ur10.urdf"), dir.path().join("urdf/ur10.urdf")).unwrap();
        let path = dir.path().join("s").join(file);
        std::fs::write(&path, &edited).unwrap();
        let outcome = std::panic::catch_unwind(|| {
            if let Ok((mut s, robot)) = Scenario::load(&path) {
                // What it accepted generates, or says why not (a few poses: the property is the
                // absence of a panic, not the dataset).
                s.sampling.poses = s.sampling.poses.min(6);
                s.sampling.test = s.sampling.test.min(1);
                let _ = generate(&s, &robot, &Silent);
            }
        });
        prop_assert!(outcome.is_ok(), "panicked after editing {:?}", edits.iter().map(|(i, n)| (paths[i.index(paths.len())].clone(), n.clone())).collect::<Vec<_>>());
    }

    #[test]
    fn an_edited_shard_part_reduces_or_is_refused(edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<prop::sample::Index>(), replacement()), 1..4)) {
        let lines = part_fixture();
        let mut lines = lines.clone();
        let mut edited = Vec::new();
        for (line, at, new) in &edits {
            let l = &mut lines[line.index(4)];
            let mut paths = Vec::new();
            leaves(l, String::new(), &mut paths);
            let p = paths[at.index(paths.len())].clone();
            if let Some(slot) = l.pointer_mut(&p) {
                *slot = new.clone();
            }
            edited.push((p, new.clone()));
        }
        let dir = tempfile::tempdir().unwrap();
        let part = dir.path().join("part.jsonl");
        std::fs::write(&part, lines.iter().map(|l| l.to_string() + "\n").collect::<String>()).unwrap();
        let outcome = std::panic::catch_unwind(|| {
            let read = twincal::jobs::shard::Parts::read(std::slice::from_ref(&part))?;
            twincal::jobs::reduce_compare(read, None, None, &twincal::jobs::NoRecordings).map(|_| ())
        });
        prop_assert!(outcome.is_ok(), "panicked after editing {edited:?}");
    }
}

/// The lines of a whole one-shard comparison (lm and rbf over two seeds on the fixture's first
/// 200 rows), as JSON.
fn part_fixture() -> &'static Vec<Value> {
    static F: OnceLock<Vec<Value>> = OnceLock::new();
    F.get_or_init(|| {
        let (_, data) = fixtures();
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("d.csv");
        Dataset { rows: data.rows[..200].to_vec(), source: "first rows".into() }.write_csv(&csv).unwrap();
        let part = dir.path().join("part.jsonl");
        let request = twincal::jobs::CompareRequest {
            methods: vec![twincal::calib::pipeline::Method::LM, twincal::calib::pipeline::Method::RBF],
            seeds: 2,
            ..Default::default()
        };
        let job = twincal::jobs::CompareJob { data: csv, request, out: None, rrd: None, shard: Some("0/1".into()), shard_out: Some(part.clone()) };
        twincal::jobs::compare(&job, &Silent, &twincal::jobs::NoRecordings).unwrap();
        let lines: Vec<Value> = std::fs::read_to_string(&part).unwrap().lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        assert_eq!(lines.len(), 4);
        // Unedited, the part reduces.
        let read = twincal::jobs::shard::Parts::read(&[part]).unwrap();
        twincal::jobs::reduce_compare(read, None, None, &twincal::jobs::NoRecordings).unwrap();
        lines
    })
}
