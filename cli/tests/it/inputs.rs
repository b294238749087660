//! Issue 6, inputs a real user sends: the generator's output precision, and a dataset the twin
//! writes for a narrow joint range read back with the angle-unit option.

use std::path::Path;
use twincal::dataset::{AngleUnit, Dataset, ReadOptions};
use twincal::sim::generate::{generate, Silent};
use twincal::sim::scenario::Scenario;

fn ideal() -> (Scenario, twincal::robot::Robot) {
    Scenario::load(&Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios/irb120_ideal.toml")).unwrap()
}

/// Largest number of decimals of each column in CSV text (header skipped).
fn decimals_per_column(text: &str) -> Vec<usize> {
    let mut widest = Vec::new();
    for line in text.lines().skip(1) {
        for (i, f) in line.split(',').enumerate() {
            let d = f.split_once('.').map_or(0, |(_, frac)| frac.len());
            if widest.len() <= i {
                widest.push(0);
            }
            widest[i] = widest[i].max(d);
        }
    }
    widest
}

#[test]
fn generated_numbers_are_written_at_their_precision() {
    let (mut s, robot) = ideal();
    s.sampling.poses = 20;
    s.sampling.test = 4;
    s.draw_wire.noise_std_mm = 0.05;
    s.draw_wire.resolution_mm = 0.01;
    s.draw_wire.samples = 50;
    s.sampling.angle_decimals = 4;
    s.validate(&robot, "patched").unwrap();
    assert_eq!(s.draw_wire.reading_decimals(), 4, "0.01 mm / 50 samples = 0.0002 mm");
    let g = generate(&s, &robot, &Silent).unwrap();
    let text = g.dataset.to_csv_string();
    assert!(text.starts_with("q1,q2,q3,q4,q5,q6,L,t,temp,split\n"), "{text}");
    let widest = decimals_per_column(&text);
    assert!(widest[..6].iter().all(|d| *d <= 4), "angles: {widest:?}\n{text}");
    assert!(widest[6] <= 4, "L: {widest:?}");
    assert!(widest[7] <= 3 && widest[8] <= 3, "t, temp: {widest:?}");
    // Some value actually uses the precision (rounding did not throw the digits away).
    assert!(widest[6] >= 3 && widest[..6].contains(&4), "{widest:?}");
    // The reader gives back exactly the rows in memory, and the same seed the same bytes.
    let back = Dataset::from_csv_reader(text.as_bytes(), "gen.csv").unwrap();
    assert_eq!(back.rows, g.dataset.rows);
    let again = generate(&s, &robot, &Silent).unwrap();
    assert_eq!(again.dataset.to_csv_string(), text);
    // Truth and dataset agree on the measured length.
    for (row, pose) in g.dataset.rows.iter().zip(&g.truth.poses) {
        assert_eq!(row.l_mm(), Some(pose.length_measured_mm));
    }

    // Without quantisation the reading keeps 6 decimals (1e-6 mm), the default angles 6.
    let (s, robot) = ideal();
    assert_eq!(s.draw_wire.reading_decimals(), 6);
    let g = generate(&s, &robot, &Silent).unwrap();
    let widest = decimals_per_column(&g.dataset.to_csv_string());
    assert!(widest[..7].iter().all(|d| *d <= 6), "{widest:?}");
}

#[test]
fn a_narrow_range_dataset_of_the_twin_reloads_with_angles_deg() {
    let (mut s, robot) = ideal();
    s.sampling.poses = 12;
    s.sampling.test = 0;
    s.sampling.ranges_deg = Some(vec![[-3.0, 3.0]; 6]);
    s.sampling.min_tool_z_mm = 0.0;
    s.validate(&robot, "narrow").unwrap();
    let g = generate(&s, &robot, &Silent).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("dataset.csv");
    g.dataset.write_csv(&path).unwrap();
    let msg = Dataset::load(&path).unwrap_err().to_string();
    assert!(msg.contains("look like radians") && msg.contains("--angles deg"), "{msg}");
    let ds = Dataset::load_with(&path, &ReadOptions { angles: AngleUnit::Deg, ..Default::default() }).unwrap();
    assert_eq!(ds.rows, g.dataset.rows);
}
