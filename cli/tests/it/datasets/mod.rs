//! Dataset edits shared by the integration tests, and the files they read from ../shared.

use std::io::Write;
use std::path::{Path, PathBuf};
use twincal::dataset::{Dataset, Row, Split};

/// `rel` under ../shared (real data and reference files beside the project, read at run time and
/// never committed), or None once [`skip`] has said it is absent.
pub fn shared(rel: &str) -> Option<PathBuf> {
    let p = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("../shared").join(rel);
    if p.exists() {
        Some(p)
    } else {
        skip(&p);
        None
    }
}

/// Says on the test process's stderr that a test skips what needs `absent`: written to the
/// stream itself, not through `eprintln!`, which the test harness captures and shows only for a
/// failing test, so a passing run would not say it skipped.
pub fn skip(absent: &Path) {
    let _ = writeln!(std::io::stderr(), "SKIP: {} is absent (read from ../shared at run time)", absent.display());
}

/// The twin's dataset of the project's scenario `name` at `seed`, with `extra` tables inserted
/// before `[sensor]`, and the scenario's robot.
pub fn generated(name: &str, seed: u64, extra: &str) -> (Dataset, twincal::robot::Robot) {
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/..")).join("scenarios").join(format!("{name}.toml"));
    let text = std::fs::read_to_string(&path).unwrap().replacen("[sensor]", &format!("{extra}\n[sensor]"), 1);
    let mut s = twincal::sim::scenario::Scenario::from_toml(&text, name).unwrap();
    s.seed = seed;
    let robot = s.load_robot(path.parent()).unwrap();
    let g = twincal::sim::generate::generate(&s, &robot, &twincal::sim::generate::Silent).unwrap();
    (g.dataset, robot)
}

/// `ds` with every test row's length moved by +0.5 or −0.7 mm (alternately): a method that
/// chooses anything on the test rows would see it.
pub fn test_lengths_scrambled(ds: &Dataset) -> Dataset {
    let rows = ds
        .rows
        .iter()
        .enumerate()
        .map(|(i, r)| match r.split {
            Some(Split::Test) => Row { reading_mm: r.reading_mm.iter().map(|l| l + if i % 2 == 0 { 0.5 } else { -0.7 }).collect(), ..r.clone() },
            _ => r.clone(),
        })
        .collect();
    Dataset { rows, source: ds.source.clone() }
}
