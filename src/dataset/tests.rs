use super::table::*;
use super::*;
use crate::error::Result;
use crate::measurement::Measurement;
use std::path::{Path, PathBuf};

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
    Row { q_deg: q.to_vec(), reading_mm: vec![l], ..Default::default() }
}

/// Says on the test process's stderr that a test skips what needs `absent` (written to the
/// stream itself: the harness captures `eprintln!` and shows it only for a failing test).
fn skip(absent: &Path) {
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "SKIP: {} is absent (read from ../shared at run time)", absent.display());
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
            Row {
                q_deg: awkward.to_vec(),
                reading_mm: vec![350.07],
                t_s: Some(0.0),
                temp_c: Some(21.5),
                split: Some(Split::Train),
                std_mm: None,
                ..Default::default()
            },
            Row {
                q_deg: vec![1.405, -74.025, 220.99, -166.357, 41.989, 65.122],
                reading_mm: vec![std::f64::consts::PI * 100.0],
                t_s: Some(0.1 + 0.2),
                temp_c: Some(-3.25e-7),
                split: Some(Split::Test),
                std_mm: None,
                ..Default::default()
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
        rows: (0..12).map(|i| row([i as f64, -74.0, 220.0 + i as f64 * 0.5, -166.0, 41.0, 65.0], 300.0 + i as f64)).collect(),
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
    // No rows: no joints to name, the length column only.
    assert_eq!(Dataset::default().to_csv_string(), "L\n");
}

// ---- accepted inputs ---------------------------------------------------------------------

#[test]
fn header_is_case_insensitive_order_free_and_extra_columns_ignored() {
    let text = "\u{feff} Split ,note, L ,Q6,q5,q4,q3,q2,Q1,TEMP,T\n\
                TEST,hello,350.5,6,5,4,3,2,1,20.5,0\n\
                \n\
                train,x,351,6,5,4,3,2,1.5,20.7,1\n\
                ,,,,,,,,,,\n";
    let ds = parse(text).expect("load");
    assert_eq!(ds.rows.len(), 2);
    assert_eq!(ds.rows[0].q_deg, [1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    assert_eq!(ds.rows[0].l_mm(), Some(350.5));
    assert_eq!(ds.rows[0].split, Some(Split::Test));
    assert_eq!(ds.rows[0].temp_c, Some(20.5));
    assert_eq!(ds.rows[1].temp_c, Some(20.7));
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
    let rows: String = (0..12).map(|i| format!("{},{},3.85,-2.9,0.73,1.136,350\n", 0.02 * i as f64, -1.3 + 0.01 * i as f64)).collect();
    let msg = err(&format!("{HEADER}\n{rows}"));
    assert_contains(&msg, &["radians", "degrees", "q1"]);
}

#[test]
fn error_pose_angles_in_radians_or_in_part() {
    let pose = |r: f64| -> String {
        let rows: String =
            (0..12).map(|i| format!("10,20,30,40,50,{},900,100,800,{},{},{}\n", i, r * (0.1 * i as f64 - 0.5), r * 0.3, r * 0.05 * i as f64)).collect();
        format!("q1,q2,q3,q4,q5,q6,x,y,z,rx,ry,rz\n{rows}")
    };
    // The same orientations in degrees read; in radians refused, naming the way out.
    assert!(parse(&pose(57.29577951308232)).is_ok());
    let msg = err(&pose(1.0));
    assert_contains(&msg, &["rx, ry, rz look like radians", "--angles deg"]);
    assert!(parse_with(&pose(1.0), &ReadOptions { angles: AngleUnit::Deg, ..Default::default() }).is_ok(), "--angles deg reads them as given");
    // rx and ry without rz: neither a pose nor a point read silently.
    let text = "q1,q2,q3,q4,q5,q6,x,y,z,rx,ry\n10,20,30,40,50,60,900,100,800,10,20\n";
    assert_contains(&err(text), &["line 1", "rx, ry given without rz", "--measurement point"]);
    let point = ReadOptions { measurement: Some(crate::measurement::Measurement::Point), ..Default::default() };
    assert_eq!(parse_with(text, &point).unwrap().rows[0].reading_mm, vec![900.0, 100.0, 800.0]);
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

    // A folder without dataset.csv and without a CSV file.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).expect("mkdir");
    let msg = Dataset::load(&empty).expect_err("empty folder").to_string();
    assert_contains(&msg, &[DATASET_FILE]);
    // A folder of CSV files without dataset.csv is a campaign: its bad file is named.
    let msg = Dataset::load(dir.path()).expect_err("a campaign with a bad file").to_string();
    assert_contains(&msg, &[&bad.display().to_string(), "line 3", "q3"]);
}

#[test]
fn a_folder_of_sessions_is_a_campaign_each_file_a_station() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("b.csv"), format!("{HEADER}\n{GOOD}\n{GOOD}\n")).expect("write");
    std::fs::write(dir.path().join("a.csv"), format!("{HEADER},station\n{GOOD},east\n{GOOD},west\n{GOOD},east\n")).expect("write");
    std::fs::write(dir.path().join("notes.txt"), "not a session").expect("write");
    let d = Dataset::load(dir.path()).expect("a campaign");
    assert_eq!(d.rows.len(), 5);
    let s = d.stations();
    assert_eq!(s.labels, vec!["east", "west", "b"]);
    assert_eq!(s.of_row, vec![0, 1, 0, 2, 2]);
    // Another instrument in one file is refused by name.
    std::fs::write(dir.path().join("c.csv"), "q1,q2,q3,q4,q5,q6,x,y,z\n1,2,3,4,5,6,700,800,900\n").expect("write");
    let msg = Dataset::load(dir.path()).expect_err("mixed instruments").to_string();
    assert_contains(&msg, &["one instrument on one arm", "c.csv"]);
}

// ---- the real HSR-RobotCali pool (skipped when absent) -----------------------------------

fn check_real_pool(ds: &Dataset) {
    assert_eq!(ds.rows.len(), 1614);
    let first = &ds.rows[0];
    assert_eq!(first.q_deg[0], 1.405);
    assert_eq!(first.l_mm(), Some(350.07));
    assert_eq!(first.q_deg, [1.405, -74.025, 220.99, -166.357, 41.989, 65.122]);
    assert!(first.t_s.is_none() && first.temp_c.is_none() && first.split.is_none());
    assert_eq!(ds.train_indices().len(), 1614);
}

#[test]
fn real_pool_csv() {
    let path = real_data_dir().join("hsr_robotcali_pool.csv");
    if !path.exists() {
        skip(&path);
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
        skip(&xlsx);
        return;
    }
    let ds = Dataset::load(&xlsx).expect("load real xlsx");
    check_real_pool(&ds);
    assert!(ds.source.ends_with("hsr_robotcali_pool.xlsx#Sheet1"), "{}", ds.source);

    let named = Dataset::load(Path::new(&format!("{}#Sheet1", xlsx.display()))).expect("load named sheet");
    assert_eq!(named.rows, ds.rows);
    let msg = Dataset::load(Path::new(&format!("{}#NoSuchSheet", xlsx.display()))).expect_err("unknown sheet").to_string();
    assert_contains(&msg, &["NoSuchSheet", "Sheet1"]);

    if csv.exists() {
        let from_csv = Dataset::load(&csv).expect("load real csv");
        assert_eq!(ds.rows, from_csv.rows, "xlsx and csv hold the same values");
    } else {
        skip(&csv);
    }
}

// ---- issue 6: inputs a real user sends ---------------------------------------------------

fn parse_with(text: &str, opts: &ReadOptions) -> Result<Dataset> {
    Dataset::from_csv_reader_with(text.as_bytes(), "test.csv", opts)
}

#[test]
fn semicolon_csv_with_decimal_commas_and_comments() {
    let text = "# exported from a spreadsheet, European locale\n\
                q1;q2;q3;q4;q5;q6;L;temp\n\
                # a comment between rows\n\
                1,405;-74,025;220,99;-166,357;41,989;65,122;350,07;21,5\n\
                2;-74;221;-166;42;65;351;22\n";
    let ds = parse(text).expect("semicolon CSV");
    assert_eq!(ds.rows.len(), 2);
    assert_eq!(ds.rows[0].q_deg, [1.405, -74.025, 220.99, -166.357, 41.989, 65.122]);
    assert_eq!(ds.rows[0].l_mm(), Some(350.07));
    assert_eq!(ds.rows[0].temp_c, Some(21.5));
    assert_eq!(ds.rows[1].l_mm(), Some(351.0));
    // Line numbers still count the comment and blank lines.
    let msg = err("# c\nq1;q2;q3;q4;q5;q6;L\n# c\n1;2;3;4;5;6;x\n");
    assert_contains(&msg, &["line 4", "column L", "'x'"]);
    let msg = err(&format!("\n{HEADER}\r\n\r\n{GOOD}\n\n\n1,2,3,4,5,6,x\n"));
    assert_contains(&msg, &["line 7", "column L"]);
    let msg = err(&format!("{HEADER}\n\n{GOOD}\n\n1,2,3,4,5,6\n"));
    assert_contains(&msg, &["line 5", "found 6"]);
    // Tab-separated works the same way; a thousands separator is not a number.
    let ds = parse("q1\tq2\tq3\tq4\tq5\tq6\tL\n1\t2\t3\t4\t5\t6\t300,25\n").expect("tab CSV");
    assert_eq!(ds.rows[0].l_mm(), Some(300.25));
    let msg = err("q1;q2;q3;q4;q5;q6;L\n1;2;3;4;5;6;1.300,25\n");
    assert_contains(&msg, &["line 2", "column L", "not a number"]);
    // In a comma-separated file a decimal comma is a field separator: the count is wrong.
    let msg = err(&format!("# note\n{HEADER}\n{GOOD}\n1,5,2,3,4,5,6,300\n"));
    assert_contains(&msg, &["line 4", "expected 7 fields", "found 8"]);
    // Comment and blank lines only: empty.
    assert_contains(&err("# nothing here\n\n# still nothing\n"), &["empty"]);
}

#[test]
fn implausible_length_time_and_temperature_are_refused() {
    for l in ["1e6", "1e200", "1e308", "100000.001"] {
        let msg = err(&format!("{HEADER}\n{GOOD}\n1,2,3,4,5,6,{l}\n"));
        assert_contains(&msg, &["line 3", "column L", "implausible", "100000"]);
    }
    assert!(parse(&format!("{HEADER}\n1,2,3,4,5,6,{MAX_L_MM}\n")).is_ok(), "the bound itself is allowed");
    let msg = err(&format!("{HEADER},temp\n{GOOD},20\n{GOOD},-400\n"));
    assert_contains(&msg, &["line 3", "column temp", "-400", "implausible"]);
    assert!(parse(&format!("{HEADER},temp\n{GOOD},-273.15\n")).is_ok(), "absolute zero itself");
    let msg = err(&format!("{HEADER},temp\n{GOOD},1e300\n"));
    assert_contains(&msg, &["line 2", "column temp"]);
    let msg = err(&format!("{HEADER},t\n{GOOD},-1\n"));
    assert_contains(&msg, &["line 2", "column t", "-1", "implausible"]);
    let msg = err(&format!("{HEADER},t\n{GOOD},0\n{GOOD},1.7e9\n"));
    assert_contains(&msg, &["line 3", "column t", "implausible"]);
}

/// Twelve degree rows within ±3° of zero, as the twin writes for a narrow joint range.
fn narrow_degrees() -> String {
    let rows: String = (0..12)
        .map(|i| {
            let a = -3.0 + 0.5 * i as f64;
            format!("{a},{},{},1.5,-2.5,{a},500.25\n", -a / 2.0, a / 3.0)
        })
        .collect();
    format!("{HEADER}\n{rows}")
}

#[test]
fn angle_unit_options() {
    let text = narrow_degrees();
    let msg = err(&text);
    assert_contains(&msg, &["look like radians", "--angles deg", "--angles rad"]);
    let deg = parse_with(&text, &ReadOptions { angles: AngleUnit::Deg, ..Default::default() }).expect("degrees on request");
    assert_eq!(deg.rows.len(), 12);
    assert_eq!(deg.rows[0].q_deg[0], -3.0);
    let rad = parse_with(&text, &ReadOptions { angles: AngleUnit::Rad, ..Default::default() }).expect("radians converted");
    for (r, d) in rad.rows.iter().zip(&deg.rows) {
        for j in 0..6 {
            assert_eq!(r.q_deg[j], d.q_deg[j].to_degrees());
        }
    }
    // Radians beyond 720° after conversion are still refused, naming both values.
    let msg =
        parse_with(&format!("{HEADER}\n1,2,3,4,13,6,300\n"), &ReadOptions { angles: AngleUnit::Rad, ..Default::default() }).expect_err("13 rad").to_string();
    assert_contains(&msg, &["line 2", "column q5", "13 rad", "implausible"]);
    assert_eq!("DEG".parse::<AngleUnit>(), Ok(AngleUnit::Deg));
    assert_eq!("radians".parse::<AngleUnit>(), Ok(AngleUnit::Rad));
    assert_eq!("auto".parse::<AngleUnit>(), Ok(AngleUnit::Auto));
    assert!("gon".parse::<AngleUnit>().unwrap_err().contains("gon"));
}

#[test]
fn poses_without_length() {
    let text = "q1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n7,8,9,10,11,12\n";
    let msg = err(text);
    assert_contains(&msg, &["missing required column(s) L"]);
    let ds = parse_with(text, &ReadOptions::poses()).expect("poses");
    assert_eq!(ds.rows.len(), 2);
    assert!(ds.rows.iter().all(|r| r.l_mm().is_none()));
    assert!(!ds.has_length());
    let msg = ds.require_length().expect_err("no L").to_string();
    assert_contains(&msg, &["test.csv", "no cable length L"]);
    assert!(ds.lengths_mm().is_err());
    // Written without an L column, and read back the same.
    let out = ds.to_csv_string();
    assert_eq!(out, "q1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n7,8,9,10,11,12\n");
    assert_eq!(parse_with(&out, &ReadOptions::poses()).expect("reload").rows, ds.rows);
    // With an L column present it must still be filled and valid; q1..q6 stay required.
    let with_l = parse_with(&format!("{HEADER}\n{GOOD}\n"), &ReadOptions::poses()).expect("L given");
    assert_eq!(with_l.rows[0].l_mm(), Some(350.07));
    assert!(with_l.has_length());
    assert_eq!(with_l.lengths_mm().expect("lengths"), vec![350.07]);
    let msg = parse_with(&format!("{HEADER}\n1,2,3,4,5,6,\n"), &ReadOptions::poses()).expect_err("empty L").to_string();
    assert_contains(&msg, &["line 2", "column L", "empty"]);
    let msg = parse_with("q1,q2,q3,q5,q6\n1,2,3,5,6\n", &ReadOptions::poses()).expect_err("q4").to_string();
    assert_contains(&msg, &["missing", "q4", "optional L"]);
}

#[test]
fn any_number_of_joints_numbered_without_gaps() {
    // Seven joints (a WAM), columns in any order, round trip with the same header.
    let ds = parse("L,q7,q1,q2,q3,q4,q5,q6\n700,7,1,2,3,4,5,6\n").expect("seven joints");
    assert_eq!(ds.n_joints(), 7);
    assert_eq!(ds.rows[0].q_deg, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    assert_eq!(ds.to_csv_string(), "q1,q2,q3,q4,q5,q6,q7,L\n1,2,3,4,5,6,7,700\n");
    // Two joints (a planar arm) are as good as six.
    let two = parse("q1,q2,L\n10,20,300\n").expect("two joints");
    assert_eq!(two.n_joints(), 2);
    // A gap in the numbering names the missing joint; q0, q01 and qx are other columns.
    let msg = err("q1,q2,q4,L\n1,2,4,300\n");
    assert_contains(&msg, &["missing", "q3"]);
    let other = parse("q0,q01,qx,q1,L\n9,9,9,1,300\n").expect("q1 only");
    assert_eq!(other.n_joints(), 1);
    // Joint columns beyond MAX_JOINTS are not joints (ignored like any other column).
    let many = format!("q1,q{},L\n1,2,300\n", MAX_JOINTS + 1);
    assert_eq!(parse(&many).expect("ignored").n_joints(), 1);
    // A dataset's joint count is checked against the arm it is used with.
    let msg = two.require_joints(6, "the robot 'irb120'").unwrap_err().to_string();
    assert_contains(&msg, &["2 joint angles", "6 joints", "irb120"]);
    assert!(ds.require_joints(7, "the WAM").is_ok());
}

// ---- spreadsheets built in the test ------------------------------------------------------

/// Writes a minimal xlsx: one sheet `Sheet1` with `sheet_data` (the `<row>` elements), the
/// given shared strings and a `<dimension>` of `dimension`.
fn write_xlsx(path: &Path, shared: &[&str], dimension: &str, sheet_data: &str) {
    use std::io::Write as _;
    let file = std::fs::File::create(path).expect("create xlsx");
    let mut zip = zip::ZipWriter::new(file);
    let opts = zip::write::SimpleFileOptions::default();
    const MAIN: &str = "http://schemas.openxmlformats.org/spreadsheetml/2006/main";
    let sst: String = shared.iter().map(|s| format!("<si><t>{s}</t></si>")).collect();
    let files = [
        (
            "[Content_Types].xml",
            r#"<?xml version="1.0" encoding="UTF-8"?><Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types"><Default Extension="xml" ContentType="application/xml"/></Types>"#.to_string(),
        ),
        (
            "xl/workbook.xml",
            format!(r#"<?xml version="1.0" encoding="UTF-8"?><workbook xmlns="{MAIN}" xmlns:r="http://schemas.openxmlformats.org/officeDocument/2006/relationships"><sheets><sheet name="Sheet1" sheetId="1" r:id="rId1"/></sheets></workbook>"#),
        ),
        (
            "xl/_rels/workbook.xml.rels",
            r#"<?xml version="1.0" encoding="UTF-8"?><Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships"><Relationship Id="rId1" Type="http://schemas.openxmlformats.org/officeDocument/2006/relationships/worksheet" Target="worksheets/sheet1.xml"/></Relationships>"#.to_string(),
        ),
        (
            "xl/sharedStrings.xml",
            format!(r#"<?xml version="1.0" encoding="UTF-8"?><sst xmlns="{MAIN}" count="{n}" uniqueCount="{n}">{sst}</sst>"#, n = shared.len()),
        ),
        (
            "xl/worksheets/sheet1.xml",
            format!(r#"<?xml version="1.0" encoding="UTF-8"?><worksheet xmlns="{MAIN}"><dimension ref="{dimension}"/><sheetData>{sheet_data}</sheetData></worksheet>"#),
        ),
    ];
    for (name, text) in files {
        zip.start_file(name, opts).expect("zip entry");
        zip.write_all(text.as_bytes()).expect("zip write");
    }
    zip.finish().expect("zip finish");
}

/// Excel column letters of a 0-based column.
fn col_name(mut c: usize) -> String {
    let mut s = Vec::new();
    loop {
        s.push(b'A' + (c % 26) as u8);
        if c < 26 {
            break;
        }
        c = c / 26 - 1;
    }
    s.reverse();
    String::from_utf8(s).expect("ascii")
}

/// `<row>` elements: header q1..q6,L as shared strings 0..6, then `n` numeric rows.
fn header_and_rows(n: usize) -> String {
    let mut xml = String::from(r#"<row r="1">"#);
    for c in 0..7 {
        xml += &format!(r#"<c r="{}1" t="s"><v>{c}</v></c>"#, col_name(c));
    }
    xml += "</row>";
    for i in 0..n {
        let r = i + 2;
        xml += &format!(r#"<row r="{r}">"#);
        let vals = [i as f64, -74.0, 220.0 + i as f64, -166.0, 41.0, 65.0, 350.5 + i as f64];
        for (c, v) in vals.iter().enumerate() {
            xml += &format!(r#"<c r="{}{r}"><v>{v}</v></c>"#, col_name(c));
        }
        xml += "</row>";
    }
    xml
}

const XLSX_HEADER: [&str; 7] = ["q1", "q2", "q3", "q4", "q5", "q6", "L"];

#[test]
fn xlsx_built_in_test_reads() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("ok.xlsx");
    write_xlsx(&path, &XLSX_HEADER, "A1:G13", &header_and_rows(12));
    let ds = Dataset::load(&path).expect("load xlsx");
    assert_eq!(ds.rows.len(), 12);
    assert_eq!(ds.rows[3].q_deg, [3.0, -74.0, 223.0, -166.0, 41.0, 65.0]);
    assert_eq!(ds.rows[3].l_mm(), Some(353.5));
    assert!(ds.source.ends_with("ok.xlsx#Sheet1"), "{}", ds.source);
}

#[test]
fn xlsx_stray_cell_far_away_is_not_a_dense_allocation() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("stray.xlsx");
    // A stray value at XFD1048576 and a used range claiming the whole sheet: a dense range would
    // be 16384 × 1048576 cells (an abort on a 512 GB allocation).
    let data = header_and_rows(12) + r#"<row r="1048576"><c r="XFD1048576"><v>7</v></c></row>"#;
    write_xlsx(&path, &XLSX_HEADER, "A1:XFD1048576", &data);
    let t0 = std::time::Instant::now();
    let ds = Dataset::load(&path).expect("stray cell outside the header's columns is ignored");
    assert_eq!(ds.rows.len(), 12);
    assert!(t0.elapsed().as_secs_f64() < 5.0, "took {:?}", t0.elapsed());

    // A stray value under a header column is a data row of its own, reported by its line.
    let path = dir.path().join("stray_in_column.xlsx");
    let data = header_and_rows(12) + r#"<row r="1048576"><c r="C1048576"><v>7</v></c></row>"#;
    write_xlsx(&path, &XLSX_HEADER, "A1:XFD1048576", &data);
    let msg = Dataset::load(&path).expect_err("stray cell in q3").to_string();
    assert_contains(&msg, &["line 1048576", "column q1", "empty"]);

    // A header far to the right still reads (only filled cells are kept).
    let path = dir.path().join("far_right.xlsx");
    let mut xml = String::from(r#"<row r="1">"#);
    for (k, c) in (16377..16384).enumerate() {
        xml += &format!(r#"<c r="{}1" t="s"><v>{k}</v></c>"#, col_name(c));
    }
    xml += r#"</row><row r="1048575">"#;
    for (k, c) in (16377..16384).enumerate() {
        xml += &format!(r#"<c r="{}1048575"><v>{}</v></c>"#, col_name(c), 10 + k * 100);
    }
    xml += "</row>";
    write_xlsx(&path, &XLSX_HEADER, "A1:XFD1048576", &xml);
    let ds = Dataset::load(&path).expect("far-right table");
    assert_eq!(ds.rows.len(), 1);
    assert_eq!(ds.rows[0].l_mm(), Some(610.0));
}

#[test]
fn xlsx_missing_shared_string_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad_sst.xlsx");
    // Header cell G1 points at shared string 99; only 7 exist.
    let data = header_and_rows(2).replacen(r#"<c r="G1" t="s"><v>6</v></c>"#, r#"<c r="G1" t="s"><v>99</v></c>"#, 1);
    assert!(data.contains("<v>99</v>"));
    write_xlsx(&path, &XLSX_HEADER, "A1:G3", &data);
    let msg = Dataset::load(&path).expect_err("missing shared string").to_string();
    assert_contains(&msg, &["bad_sst.xlsx", "malformed"]);
}

#[test]
fn files_that_are_not_spreadsheets() {
    let dir = tempfile::tempdir().expect("tempdir");
    let csv_named_xlsx = dir.path().join("pool.xlsx");
    std::fs::write(&csv_named_xlsx, format!("{HEADER}\n{GOOD}\n")).expect("write");
    let msg = Dataset::load(&csv_named_xlsx).expect_err("csv text").to_string();
    assert_contains(&msg, &["pool.xlsx", "not a spreadsheet", "looks like CSV text", "rename it to .csv"]);
    assert!(!msg.contains("EOCD"), "{msg}");

    let empty = dir.path().join("empty.xlsx");
    std::fs::write(&empty, b"").expect("write");
    assert_contains(&Dataset::load(&empty).expect_err("empty").to_string(), &["not a spreadsheet", "empty"]);

    let binary = dir.path().join("noise.ods");
    std::fs::write(&binary, [0u8, 159, 146, 150, 1, 2, 3]).expect("write");
    assert_contains(&Dataset::load(&binary).expect_err("binary").to_string(), &["not a spreadsheet", "00 9f 92 96"]);

    // A zip that is not a workbook: calamine's own error, no panic.
    let zip_only = dir.path().join("archive.xlsx");
    {
        let mut z = zip::ZipWriter::new(std::fs::File::create(&zip_only).expect("create"));
        z.start_file("readme.txt", zip::write::SimpleFileOptions::default()).expect("entry");
        std::io::Write::write_all(&mut z, b"hello").expect("write");
        z.finish().expect("finish");
    }
    assert_contains(&Dataset::load(&zip_only).expect_err("not a workbook").to_string(), &["archive.xlsx", "cannot open spreadsheet"]);

    // An .xlsx saved as .xls.
    let xls = dir.path().join("renamed.xls");
    std::fs::copy(&zip_only, &xls).expect("copy");
    assert_contains(&Dataset::load(&xls).expect_err("zip as xls").to_string(), &["rename it to .xlsx"]);
}

// ---- property tests ----------------------------------------------------------------------

/// The documented invariants of every accepted dataset.
fn assert_invariants(ds: &Dataset, opts: &ReadOptions) {
    assert!(!ds.rows.is_empty());
    let mut last_t = f64::NEG_INFINITY;
    for r in &ds.rows {
        assert_eq!(r.q_deg.len(), 6);
        for &q in &r.q_deg {
            assert!(q.is_finite() && q.abs() <= MAX_ABS_JOINT_DEG, "q = {q}");
        }
        match r.reading_mm[..] {
            [l] => assert!(l.is_finite() && l > 0.0 && l <= MAX_L_MM, "L = {l}"),
            [] => assert!(!opts.require_length, "reading missing although required"),
            ref p => assert!(p.len() == 3 && p.iter().all(|v| v.is_finite() && v.abs() <= MAX_L_MM), "point = {p:?}"),
        }
        if let Some(t) = r.t_s {
            assert!(t.is_finite() && (0.0..=MAX_T_S).contains(&t) && t >= last_t, "t = {t}");
            last_t = t;
        }
        if let Some(temp) = r.temp_c {
            assert!(temp.is_finite() && (MIN_TEMP_C..=MAX_TEMP_C).contains(&temp), "temp = {temp}");
        }
    }
    // The reading is all or nothing and of one kind, and so is the split.
    let d = ds.rows[0].reading_mm.len();
    assert!(ds.rows.iter().all(|r| r.reading_mm.len() == d));
    assert!(ds.rows.iter().all(|r| r.split.is_some()) || ds.rows.iter().all(|r| r.split.is_none()));
    if opts.require_length {
        assert!(ds.has_readings());
    }
    // What the writer writes reads back to the same rows (angles are degrees by now; optional
    // columns only some rows fill are not written).
    let again = ReadOptions { angles: AngleUnit::Deg, ..*opts };
    let back = Dataset::from_csv_reader_with(ds.to_csv_string().as_bytes(), "again.csv", &again);
    let back = back.expect("a written dataset reloads");
    let all = |f: fn(&Row) -> bool| ds.rows.iter().all(f);
    let (has_t, has_temp) = (all(|r| r.t_s.is_some()), all(|r| r.temp_c.is_some()));
    let expected: Vec<Row> = ds.rows.iter().map(|r| Row { t_s: r.t_s.filter(|_| has_t), temp_c: r.temp_c.filter(|_| has_temp), ..r.clone() }).collect();
    assert_eq!(back.rows, expected);
}

mod props {
    use super::*;
    use proptest::prelude::*;

    fn opts() -> impl Strategy<Value = ReadOptions> {
        (prop_oneof![Just(AngleUnit::Auto), Just(AngleUnit::Deg), Just(AngleUnit::Rad)], any::<bool>()).prop_map(|(angles, require_length)| ReadOptions {
            angles,
            require_length,
            ..Default::default()
        })
    }

    /// Numbers a spreadsheet or a CSV could hold, weighted towards the awkward ones.
    fn number() -> impl Strategy<Value = f64> {
        prop_oneof![
            4 => -800.0..800.0f64,
            2 => 0.0..3000.0f64,
            1 => Just(f64::NAN),
            1 => Just(f64::INFINITY),
            1 => Just(f64::NEG_INFINITY),
            1 => prop_oneof![Just(1e308), Just(-1e308), Just(1e200), Just(1e6), Just(-400.0), Just(0.0), Just(-0.0)],
            1 => any::<f64>(),
        ]
    }

    fn cell() -> impl Strategy<Value = Cell> {
        prop_oneof![
            6 => number().prop_map(Cell::Number),
            3 => number().prop_map(|v| Cell::Text(v.to_string())),
            1 => Just(Cell::Empty),
            1 => "[a-z0-9,.;#-]{1,6}".prop_map(Cell::Text),
            1 => prop_oneof![Just("train"), Just("test"), Just("TEST")].prop_map(|s| Cell::Text(s.into())),
            1 => Just(Cell::Other("boolean true".into())),
        ]
    }

    /// A header: a random order of some known columns (sometimes duplicated) and strangers.
    fn header() -> impl Strategy<Value = Vec<String>> {
        let names = ["q1", "q2", "q3", "q4", "q5", "q6", "L", "t", "temp", "split", "note", "Q3", " l ", "x", "y", "z"];
        (proptest::sample::subsequence(names.to_vec(), 5..=names.len()), any::<u64>()).prop_map(|(mut h, seed)| {
            // A deterministic shuffle from the seed.
            let n = h.len();
            let mut s = seed;
            for i in (1..n).rev() {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                h.swap(i, (s >> 33) as usize % (i + 1));
            }
            h.into_iter().map(String::from).collect()
        })
    }

    fn table() -> impl Strategy<Value = RawTable> {
        (header(), 1..14usize, any::<bool>()).prop_flat_map(|(header, n, decimal_comma)| {
            let w = header.len();
            (Just(header), proptest::collection::vec(proptest::collection::vec(cell(), 0..=w + 1), n), Just(decimal_comma)).prop_map(
                |(header, rows, decimal_comma)| RawTable {
                    header,
                    rows: rows.into_iter().enumerate().map(|(i, cells)| RawRow { line: i + 2, cells }).collect(),
                    decimal_comma,
                },
            )
        })
    }

    /// CSV-ish text: a header line of known names, then lines of numbers, words and separators.
    fn csv_text() -> impl Strategy<Value = String> {
        let line = proptest::collection::vec(
            prop_oneof![
                4 => number().prop_map(|v| v.to_string()),
                1 => "[0-9]{1,3},[0-9]{1,3}",
                1 => "[ a-z#\"]{0,4}",
            ],
            0..10,
        );
        (header(), prop_oneof![Just(","), Just(";"), Just("\t")], proptest::collection::vec(line, 0..12)).prop_map(|(h, sep, lines)| {
            let mut s = h.join(sep);
            for l in lines {
                s.push('\n');
                s += &l.join(sep);
            }
            s
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn table_interpretation_never_panics_and_keeps_invariants(t in table(), o in opts()) {
            if let Ok(ds) = from_table(t, "prop".into(), &o) {
                assert_invariants(&ds, &o);
            }
        }

        #[test]
        fn csv_text_never_panics_and_keeps_invariants(text in csv_text(), o in opts()) {
            if let Ok(ds) = Dataset::from_csv_reader_with(text.as_bytes(), "prop.csv", &o) {
                assert_invariants(&ds, &o);
            }
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400), o in opts()) {
            let mut text = b"q1,q2,q3,q4,q5,q6,L\n".to_vec();
            text.extend_from_slice(&bytes);
            for input in [&bytes[..], &text[..]] {
                match Dataset::from_csv_reader_with(input, "bytes.csv", &o) {
                    Ok(ds) => assert_invariants(&ds, &o),
                    Err(e) => {
                        prop_assert!(e.to_string().contains("bytes.csv"));
                    }
                }
            }
        }
    }
}

#[test]
fn a_time_or_temperature_column_with_gaps_is_refused_and_an_empty_one_is_no_column() {
    let msg = err("q1,q2,q3,q4,q5,q6,L,t,temp\n1,2,3,4,5,6,300,0,21\n1,2,3,4,5,7,301,1,\n");
    assert_contains(&msg, &["line 3", "column temp", "empty temp value", "every row must"]);
    let msg = err("q1,q2,q3,q4,q5,q6,L,t\n1,2,3,4,5,6,300,\n1,2,3,4,5,7,301,1\n");
    assert_contains(&msg, &["line 2", "column t", "empty t value"]);
    let ds = parse("q1,q2,q3,q4,q5,q6,L,t,temp\n1,2,3,4,5,6,300,,21\n1,2,3,4,5,7,301,,22\n").expect("t empty everywhere");
    assert!(ds.rows.iter().all(|r| r.t_s.is_none() && r.temp_c.is_some()));
}

#[test]
fn a_tracker_file_reads_its_points_and_round_trips() {
    let text = "row,q1,q2,q3,q4,q5,q6,x,y,z,x_target,temp\n0,1,2,3,4,5,6,412.5,-30.25,601,412.4,21.5\n1,2,3,4,5,6,7,-410,31.125,-2.5,1,21.6\n";
    let ds = parse(text).unwrap();
    assert_eq!(ds.measurement(), Some(Measurement::Point));
    assert_eq!(ds.rows[0].reading_mm, vec![412.5, -30.25, 601.0]);
    assert_eq!(ds.rows[1].l_mm(), None, "a point is not a cable length");
    assert!(ds.has_readings() && !ds.has_length());
    let again = Dataset::from_csv_reader(ds.to_csv_string().as_bytes(), "again.csv").unwrap();
    assert_eq!(again.rows, ds.rows);
    assert!(ds.to_csv_string().starts_with("q1,q2,q3,q4,q5,q6,x,y,z,temp\n"), "{}", ds.to_csv_string());
    // A command that reads cable lengths names what the file holds instead.
    assert_contains(&ds.require_length().unwrap_err().to_string(), &["laser-tracker target position (x, y, z)", "cable length L"]);
}

#[test]
fn tracker_columns_are_checked_like_lengths() {
    // x and y without z: the missing coordinate is named.
    assert_contains(&err("q1,q2,q3,q4,q5,q6,x,y\n1,2,3,4,5,6,7,8\n"), &["missing required column(s) z"]);
    // Two instruments in one file.
    assert_contains(&err("q1,q2,q3,q4,q5,q6,L,x,y,z\n1,2,3,4,5,6,500,1,2,3\n"), &["two instruments", "L (draw-wire cable length)", "x, y, z"]);
    // Points in metres.
    let metres: String = (0..12).map(|i| format!("{i},2,3,4,5,6,0.4,-0.{i},0.6\n")).collect();
    assert_contains(&err(&format!("q1,q2,q3,q4,q5,q6,x,y,z\n{metres}")), &["x, y, z look like metres", "millimetres"]);
    // An empty or implausible coordinate names its line and column.
    assert_contains(&err("q1,q2,q3,q4,q5,q6,x,y,z\n1,2,3,4,5,6,400,,600\n"), &["line 2, column y", "empty cell"]);
    assert_contains(&err("q1,q2,q3,q4,q5,q6,x,y,z\n1,2,3,4,5,6,400,1e6,600\n"), &["line 2, column y", "implausible"]);
    // Without readings the hint names both instruments.
    assert_contains(&err("q1,q2,q3,q4,q5,q6\n1,2,3,4,5,6\n"), &["missing required column(s) L", "x, y, z (laser-tracker target position)"]);
}

#[test]
fn per_row_standard_deviations_are_read_checked_and_written() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("s.csv");
    let head = "q1,q2,q3,q4,q5,q6,x,y,z,sx,sy,sz\n";
    std::fs::write(&f, format!("{head}1,2,3,4,5,6,1000,200,300,0.01,0.02,0.03\n1,2,3,4,5,7,1000,200,301,,,\n")).unwrap();
    let ds = Dataset::load(&f).unwrap();
    assert_eq!(ds.rows[0].std_mm, Some([0.01, 0.02, 0.03]));
    assert_eq!(ds.rows[1].std_mm, None);
    // Written back as read.
    let g = dir.path().join("g.csv");
    ds.write_csv(&g).unwrap();
    assert_eq!(Dataset::load(&g).unwrap().rows, ds.rows);
    assert!(std::fs::read_to_string(&g).unwrap().starts_with("q1,q2,q3,q4,q5,q6,x,y,z,sx,sy,sz\n"));
    let bad = |text: &str| {
        std::fs::write(&f, text).unwrap();
        Dataset::load(&f).unwrap_err().to_string()
    };
    let e = bad("q1,q2,q3,q4,q5,q6,x,y,z,sx,sy\n1,2,3,4,5,6,1000,200,300,0.01,0.02\n");
    assert!(e.contains("need all of sx, sy, sz; missing sz"), "{e}");
    let e = bad(&format!("{head}1,2,3,4,5,6,1000,200,300,0.01,-0.02,0.03\n"));
    assert!(e.contains("line 2, column sy") && e.contains("implausible"), "{e}");
    let e = bad(&format!("{head}1,2,3,4,5,6,1000,200,300,0.01,,0.03\n"));
    assert!(e.contains("line 2, column sy") && e.contains("together"), "{e}");
    let e = bad(&format!("{head}1,2,3,4,5,6,1000,200,300,0.01,NaN,0.03\n"));
    assert!(e.contains("column sy") && e.contains("NaN"), "{e}");
    let e = bad("q1,q2,q3,q4,q5,q6,L,sx,sy,sz\n1,2,3,4,5,6,1000,0.01,0.02,0.03\n");
    assert!(e.contains("tracker's per-axis standard deviations"), "{e}");
}

#[test]
fn a_declared_block_column_is_read_checked_and_written() {
    let text = format!("{HEADER},block\n{GOOD},sweep A\n{GOOD},sweep A\n{GOOD},7\n");
    let ds = parse(&text).unwrap();
    assert_eq!(ds.rows.iter().map(|r| r.block.clone().unwrap()).collect::<Vec<_>>(), vec!["sweep A", "sweep A", "7"]);
    // Written back as read; a file without the column has no blocks.
    let again = parse(&ds.to_csv_string()).unwrap();
    assert_eq!(again.rows, ds.rows);
    assert!(ds.to_csv_string().starts_with("q1,q2,q3,q4,q5,q6,L,block\n"));
    assert!(parse(&format!("{HEADER}\n{GOOD}\n")).unwrap().rows[0].block.is_none());
    // Every row names its block when the column is there.
    assert_contains(&err(&format!("{HEADER},block\n{GOOD},a\n{GOOD},\n")), &["line 3, column block", "every row must name its block"]);
    // The detected blocks split where the label changes.
    let (b, _) = blocks::detect(&ds, None);
    assert_eq!(b.of_row, vec![0, 0, 1]);
}
