//! `twincal bench planes`: a touch probe on a block's faces on the twin over seeds
//! ([`twincal::artifact_check::check`]): calibrated from the contacts alone (the step between the
//! block's two parallel faces stated), judged on tracker points of the same arm no fit saw (the
//! tracker registered on other points), beside the nominal arm and a tracker calibration from as
//! many rows; and the time of the faces' calibration.

use super::sockets::{rows, Case, Variant};
use std::path::Path;
use twincal::error::Result;

/// The cases: (label, scenario file).
const CASES: [Case; 3] = [
    ("IRB 120, a block of four faces (a 25 mm step, two sides), three placements, 30 contacts per face", "irb120_planes"),
    ("UR10, the same block and contacts", "ur10_planes"),
    ("Barrett WAM (7 joints), the same block and contacts", "wam_planes"),
];

/// The probe's and the block's variants: (label, edit of the scenario's text). The scenarios'
/// probe pre-travels 4 µm with 2 µm of lobing and a 0.5 µm trigger scatter; the block's high
/// face was made 2 µm off and it is touched 1 K above the temperature it was made at.
const VARIANTS: [Variant; 3] = [
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
    rows(dir, seeds, &CASES, &VARIANTS)
}
