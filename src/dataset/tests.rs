use super::*;

const HEADER: &str = "q1,q2,q3,q4,q5,q6,L";
/// A plausible data row (degrees, mm).
const GOOD: &str = "1.405,-74.025,220.99,-166.357,41.989,65.122,350.07";

fn parse(text: &str) -> Result<Dataset> {
    Dataset::from_csv_reader(text.as_bytes(), "test.csv")
}

/// The error message for `text`, which must fail to load; it always names the source.
fn err(text: &str) -> String {
    let msg = match parse(text) {
        Ok(d) => panic!("expected an error, loaded {} rows", d.rows.len()),
        Err(e) => e.to_string(),
    };
    assert!(msg.contains("test.csv"), "message does not name the file: {msg}");
    msg
}

fn assert_contains(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message {msg:?} does not contain {p:?}");
    }
}

fn row(q: [f64; 6], l: f64) -> Row {
    Row { q_deg: q, l_mm: l, t_s: None, temp_c: None, split: None }
}

fn real_data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/hsr-robotcali")
}

// ---- round trip and writing --------------------------------------------------------------

#[test]
fn round_trip_is_exact() {
    let awkward = [0.1 + 0.2, -1.0 / 3.0, 719.999_999_999_999_9, 1e-300, -0.0, 123.456_789_012_345_68];
    let ds = Dataset {
        rows: vec![
            Row { q_deg: awkward, l_mm: 350.07, t_s: Some(0.0), temp_c: Some(21.5), split: Some(Split::Train) },
            Row {
                q_deg: [1.405, -74.025, 220.99, -166.357, 41.989, 65.122],
                l_mm: std::f64::consts::PI * 100.0,
                t_s: Some(0.1 + 0.2),
                temp_c: Some(-3.25e-7),
                split: Some(Split::Test),
            },
        ],
        source: "mem".into(),
    };
    let text = ds.to_csv_string();
    assert!(text.starts_with("q1,q2,q3,q4,q5,q6,L,t,temp,split\n"), "{text}");
    assert_eq!(text, ds.to_csv_string(), "output must be deterministic");
    let back = parse(&text).expect("reload");
    assert_eq!(back.rows, ds.rows);
    for (a, b) in back.rows.iter().zip(&ds.rows) {
        for (x, y) in a.q_deg.iter().zip(&b.q_deg) {
            assert_eq!(x.to_bits(), y.to_bits(), "bit-exact round trip");
        }
    }
}

#[test]
fn write_csv_then_load_folder_and_file() {
    let dir = tempfile::tempdir().expect("tempdir");
    let ds = Dataset {
        rows: (0..12)
            .map(|i| row([i as f64, -74.0, 220.0 + i as f64 * 0.5, -166.0, 41.0, 65.0], 300.0 + i as f64))
            .collect(),
        source: String::new(),
    };
    let file = dir.path().join(DATASET_FILE);
    ds.write_csv(&file).expect("write");
    let from_dir = Dataset::load(dir.path()).expect("load folder");
    let from_file = Dataset::load(&file).expect("load file");
    assert_eq!(from_dir.rows, ds.rows);
    assert_eq!(from_file.rows, ds.rows);
    assert_eq!(from_file.source, file.display().to_string());
}

#[test]
fn optional_columns_written_only_when_every_row_has_them() {
    let mut a = row([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], 300.0);
    a.t_s = Some(1.0);
    a.split = Some(Split::Train);
    let mut b = a.clone();
    b.t_s = None;
    b.split = Some(Split::Test);
    let ds = Dataset { rows: vec![a, b], source: String::new() };
    let text = ds.to_csv_string();
    assert_eq!(text, "q1,q2,q3,q4,q5,q6,L,split\n1,2,3,4,5,6,300,train\n1,2,3,4,5,6,300,test\n");
    assert_eq!(Dataset::default().to_csv_string(), "q1,q2,q3,q4,q5,q6,L\n");
}

// ---- accepted inputs ---------------------------------------------------------------------

#[test]
fn header_is_case_insensitive_order_free_and_extra_columns_ignored() {
    let text = "\u{feff} Split ,note, L ,Q6,q5,q4,q3,q2,Q1,TEMP,T\n\
                TEST,hello,350.5,6,5,4,3,2,1,20.5,0\n\
                \n\
                train,x,351,6,5,4,3,2,1.5,,1\n\
                ,,,,,,,,,,\n";
    let ds = parse(text).expect("load");
    assert_eq!(ds.rows.len(), 2);
    assert_eq!(ds.rows[0].q_deg, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    assert_eq!(ds.rows[0].l_mm, 350.5);
    assert_eq!(ds.rows[0].split, Some(Split::Test));
    assert_eq!(ds.rows[0].temp_c, Some(20.5));
    assert_eq!(ds.rows[1].temp_c, None);
    assert_eq!(ds.rows[1].t_s, Some(1.0));
    assert_eq!(ds.source, "test.csv");
}

#[test]
fn train_and_test_indices() {
    let text = format!("{HEADER},split\n{GOOD},train\n{GOOD},test\n{GOOD},TRAIN\n");
    let ds = parse(&text).expect("load");
    assert_eq!(ds.train_indices(), vec![0, 2]);
    assert_eq!(ds.test_indices(), vec![1]);

    let ds = parse(&format!("{HEADER}\n{GOOD}\n{GOOD}\n")).expect("load");
    assert_eq!(ds.train_indices(), vec![0, 1]);
    assert!(ds.test_indices().is_empty());

    // An entirely empty split column means "no split".
    let ds = parse(&format!("{HEADER},split\n{GOOD},\n{GOOD},\n")).expect("load");
    assert_eq!(ds.train_indices(), vec![0, 1]);
}

#[test]
fn radians_heuristic_spares_fixed_home_pose_and_small_files() {
    // Repeated zero pose: small values but no motion.
    let zeros: String = (0..15).map(|_| "0,0,0,0,0,0,400\n").collect();
    assert_eq!(parse(&format!("{HEADER}\n{zeros}")).expect("home pose").rows.len(), 15);
    // Fewer than RADIANS_MIN_ROWS rows: not judged.
    let few: String = (0..RADIANS_MIN_ROWS - 1).map(|i| format!("{},1,1,1,1,1,400\n", i as f64 * 0.3)).collect();
    assert!(parse(&format!("{HEADER}\n{few}")).is_ok());
}

// ---- errors ------------------------------------------------------------------------------

#[test]
fn error_missing_columns() {
    let msg = err("q1,q2,q4,q5,q6,length\n1,2,3,4,5,6\n");
    assert_contains(&msg, &["missing", "q3", "L", "header found: q1,q2,q4,q5,q6,length"]);
}

#[test]
fn error_duplicate_column() {
    let msg = err(&format!("{HEADER},Q2\n{GOOD},1\n"));
    assert_contains(&msg, &["duplicate column q2", "line 1"]);
}

#[test]
fn error_not_a_number() {
    let msg = err(&format!("{HEADER}\n{GOOD}\n1,2,3,abc,5,6,300\n"));
    assert_contains(&msg, &["line 3", "column q4", "'abc' is not a number"]);
}

#[test]
fn error_nan_and_infinite() {
    let msg = err(&format!("{HEADER}\n1,2,NaN,4,5,6,300\n"));
    assert_contains(&msg, &["line 2", "q3", "NaN"]);
    let msg = err(&format!("{HEADER}\n{GOOD}\n{GOOD}\n1,2,3,4,5,6,inf\n"));
    assert_contains(&msg, &["line 4", "column L", "infinite"]);
    let msg = err(&format!("{HEADER},temp\n{GOOD},-infinity\n"));
    assert_contains(&msg, &["column temp", "infinite"]);
}

#[test]
fn error_empty_required_cell() {
    let msg = err(&format!("{HEADER}\n1,2,3,4,5,,300\n"));
    assert_contains(&msg, &["line 2", "column q6", "empty"]);
}

#[test]
fn error_empty_file_and_no_rows() {
    assert_contains(&err(""), &["empty"]);
    assert_contains(&err("\n\n"), &["empty"]);
    assert_contains(&err(&format!("{HEADER}\n")), &["no data rows"]);
}

#[test]
fn error_wrong_field_count() {
    let msg = err(&format!("{HEADER}\n{GOOD}\n{GOOD}\n{GOOD}\n1,2,3,4,5,6\n"));
    assert_contains(&msg, &["line 5", "malformed", "expected 7 fields", "found 6"]);
    let msg = err(&format!("{HEADER}\n{GOOD},9\n"));
    assert_contains(&msg, &["line 2", "found 8"]);
}

#[test]
fn error_unknown_or_partial_split() {
    let msg = err(&format!("{HEADER},split\n{GOOD},train\n{GOOD},validation\n"));
    assert_contains(&msg, &["line 3", "column split", "'validation'", "train or test"]);
    let msg = err(&format!("{HEADER},split\n{GOOD},train\n{GOOD},\n"));
    assert_contains(&msg, &["line 3", "column split", "every row"]);
}

#[test]
fn error_non_positive_length() {
    let msg = err(&format!("{HEADER}\n{GOOD}\n1,2,3,4,5,6,-3\n"));
    assert_contains(&msg, &["line 3", "column L", "positive", "-3"]);
    let msg = err(&format!("{HEADER}\n1,2,3,4,5,6,0\n"));
    assert_contains(&msg, &["line 2", "column L", "positive"]);
}

#[test]
fn error_radians() {
    let rows: String =
        (0..12).map(|i| format!("{},{},3.85,-2.9,0.73,1.136,350\n", 0.02 * i as f64, -1.3 + 0.01 * i as f64)).collect();
    let msg = err(&format!("{HEADER}\n{rows}"));
    assert_contains(&msg, &["radians", "degrees", "q1"]);
}

#[test]
fn error_implausible_angle() {
    let msg = err(&format!("{HEADER}\n{GOOD}\n1,2,3,4,-720.5,6,300\n"));
    assert_contains(&msg, &["line 3", "column q5", "implausible", "720"]);
    assert!(parse(&format!("{HEADER}\n1,2,3,4,-720,6,300\n")).is_ok(), "720 itself is allowed");
}

#[test]
fn error_time_decreasing() {
    let msg = err(&format!("{HEADER},t\n{GOOD},0\n{GOOD},2\n{GOOD},2\n{GOOD},1.5\n"));
    assert_contains(&msg, &["line 5", "column t", "non-decreasing", "line 4"]);
    // Empty t cells are allowed and do not reset the ordering.
    let msg = err(&format!("{HEADER},t\n{GOOD},3\n{GOOD},\n{GOOD},1\n"));
    assert_contains(&msg, &["line 4", "line 2"]);
}

#[test]
fn error_metres() {
    let msg = err(&format!("{HEADER}\n1,2,3,4,5,6,0.35\n1,2,3,4,5,6,0.41\n"));
    assert_contains(&msg, &["L looks like metres", "millimetres"]);
}

#[test]
fn error_malformed_quoting_or_utf8() {
    let bytes: &[u8] = b"q1,q2,q3,q4,q5,q6,L\n1,2,3,4,5,6,\xff\xfe\n";
    let msg = Dataset::from_csv_reader(bytes, "test.csv").expect_err("invalid UTF-8").to_string();
    assert_contains(&msg, &["test.csv", "line 2"]);
}

#[test]
fn load_errors_name_the_path() {
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, format!("{HEADER}\n{GOOD}\n1,2,x,4,5,6,300\n")).expect("write");
    let msg = Dataset::load(&bad).expect_err("bad cell").to_string();
    assert_contains(&msg, &[&bad.display().to_string(), "line 3", "q3"]);

    let missing = dir.path().join("nope.csv");
    let msg = Dataset::load(&missing).expect_err("missing").to_string();
    assert_contains(&msg, &["nope.csv"]);

    let msg = Dataset::load(&dir.path().join("data.txt")).expect_err("unsupported").to_string();
    assert_contains(&msg, &["data.txt", "unsupported"]);

    // A folder without dataset.csv.
    let msg = Dataset::load(dir.path()).expect_err("empty folder").to_string();
    assert_contains(&msg, &[DATASET_FILE]);
}

// ---- the real HSR-RobotCali pool (skipped when absent) -----------------------------------

fn check_real_pool(ds: &Dataset) {
    assert_eq!(ds.rows.len(), 1614);
    let first = &ds.rows[0];
    assert_eq!(first.q_deg[0], 1.405);
    assert_eq!(first.l_mm, 350.07);
    assert_eq!(first.q_deg, [1.405, -74.025, 220.99, -166.357, 41.989, 65.122]);
    assert!(first.t_s.is_none() && first.temp_c.is_none() && first.split.is_none());
    assert_eq!(ds.train_indices().len(), 1614);
}

#[test]
fn real_pool_csv() {
    let path = real_data_dir().join("hsr_robotcali_pool.csv");
    if !path.exists() {
        eprintln!("SKIP real_pool_csv: {} not found", path.display());
        return;
    }
    let ds = Dataset::load(&path).expect("load real csv");
    check_real_pool(&ds);
}

#[test]
fn real_pool_xlsx_matches_csv() {
    let dir = real_data_dir();
    let (xlsx, csv) = (dir.join("hsr_robotcali_pool.xlsx"), dir.join("hsr_robotcali_pool.csv"));
    if !xlsx.exists() {
        eprintln!("SKIP real_pool_xlsx_matches_csv: {} not found", xlsx.display());
        return;
    }
    let ds = Dataset::load(&xlsx).expect("load real xlsx");
    check_real_pool(&ds);
    assert!(ds.source.ends_with("hsr_robotcali_pool.xlsx#Sheet1"), "{}", ds.source);

    let named = Dataset::load(Path::new(&format!("{}#Sheet1", xlsx.display()))).expect("load named sheet");
    assert_eq!(named.rows, ds.rows);
    let msg =
        Dataset::load(Path::new(&format!("{}#NoSuchSheet", xlsx.display()))).expect_err("unknown sheet").to_string();
    assert_contains(&msg, &["NoSuchSheet", "Sheet1"]);

    if csv.exists() {
        let from_csv = Dataset::load(&csv).expect("load real csv");
        assert_eq!(ds.rows, from_csv.rows, "xlsx and csv hold the same values");
    } else {
        eprintln!("SKIP csv comparison: {} not found", csv.display());
    }
}
