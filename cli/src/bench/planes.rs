//! `twincal bench planes`: a touch probe on a block's faces on the twin over seeds
//! ([`twincal::artifact_check::check`]): calibrated from the contacts alone (the step between the
//! block's two parallel faces stated), judged on tracker points of the same arm no fit saw (the
//! tracker registered on other points), beside the nominal arm and a tracker calibration from as
//! many rows; and the time of the faces' calibration.

use super::compensate::mean_sd;
use super::sockets::load_case;
use std::path::Path;
use std::time::Instant;
use twincal::artifact_check::{check, ArtifactCheck};
use twincal::error::Result;
use twincal::sim::scenario::Scenario;

/// The cases: (label, scenario file).
const CASES: [(&str, &str); 3] = [
    ("IRB 120, a block of four faces (a 25 mm step, two sides), three placements, 30 contacts per face", "irb120_planes"),
    ("UR10, the same block and contacts", "ur10_planes"),
    ("Barrett WAM (7 joints), the same block and contacts", "wam_planes"),
];

/// The probe's and the block's variants: (label, edit of the scenario's text). The scenarios'
/// probe pre-travels 4 µm with 2 µm of lobing and a 0.5 µm trigger scatter; the block's high
/// face was made 2 µm off and it is touched 1 K above the temperature it was made at.
const VARIANTS: [(&str, &[(&str, &str)]); 3] = [
    (
        "exact probe (no pre-travel, lobing or scatter), exact block at 20 °C",
        &[
            ("pretravel_um = 4.0", "pretravel_um = 0.0"),
            ("lobing_um = 2.0", "lobing_um = 0.0"),
            ("trigger_std_um = 0.5", "trigger_std_um = 0.0"),
            ("made_error_mm = [0.0, 0.002, 0.0, 0.0]", "made_error_mm = [0.0, 0.0, 0.0, 0.0]"),
            ("expansion_ppm_per_k = 12.0", "expansion_ppm_per_k = 0.0"),
        ],
    ),
    (
        "probe as used (pre-travel 4 µm with 2 µm lobing, 0.5 µm trigger scatter), exact block at 20 °C",
        &[("made_error_mm = [0.0, 0.002, 0.0, 0.0]", "made_error_mm = [0.0, 0.0, 0.0, 0.0]"), ("expansion_ppm_per_k = 12.0", "expansion_ppm_per_k = 0.0")],
    ),
    ("probe as used; the step made 2 µm long (80 ppm of 25 mm), steel 1 K warm", &[]),
];

/// Runs every case over `seeds` seeds and prints the table.
pub fn bench_planes(seeds: u64) -> Result<()> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    println!("# A touch probe on a block's faces on the twin ({seeds} seeds): calibrated from the contacts alone, judged on 100 tracker points no fit saw after registering the tracker on 200 others; |Δp| RMS over the points, mm, mean ± sd over seeds\n");
    println!("| case | probe and block | contacts (train) | contacts' test RMSE | nominal | faces | tracker, as many rows | faces / tracker (worst seed) | calibration time (median) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for ((label, file), (variant, edits)) in CASES.iter().flat_map(|c| VARIANTS.iter().map(move |v| (c, v))) {
        let (s0, robot, opts) = load_case(dir, file, edits)?;
        let mut times = Vec::new();
        let checks: Vec<ArtifactCheck> = (1..=seeds)
            .map(|seed| {
                let t0 = Instant::now();
                let c = check(&Scenario { seed, ..s0.clone() }, &robot, &opts);
                times.push(t0.elapsed().as_secs_f64());
                c
            })
            .collect::<Result<_>>()?;
        let col = |f: &dyn Fn(&ArtifactCheck) -> f64| {
            let (m, sd) = mean_sd(&checks.iter().map(f).collect::<Vec<_>>());
            format!("{m:.4} ± {sd:.4}")
        };
        let worst = checks.iter().map(|c| c.artifact_mm / c.tracker_mm).fold(0.0, f64::max);
        times.sort_by(f64::total_cmp);
        println!(
            "| {label} | {variant} | {} | {} | {} | {} | {} | {worst:.2} | {:.2} s |",
            checks[0].artifact_rows,
            col(&|c| c.artifact_test_rmse_mm),
            col(&|c| c.nominal_mm),
            col(&|c| c.artifact_mm),
            col(&|c| c.tracker_mm),
            times[times.len() / 2]
        );
    }
    Ok(())
}
