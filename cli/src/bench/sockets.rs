//! `twincal bench sockets`: a ball seated in an artifact's sockets on the twin over seeds
//! ([`twincal::artifact_check`]): calibrated from the seated rows alone, judged on tracker points
//! of the same arm no fit saw (the tracker registered on other points), beside the nominal arm
//! and a tracker calibration from as many rows; and the time of the sockets' calibration.

use super::compensate::mean_sd;
use std::path::Path;
use std::time::Instant;
use twincal::artifact_check::{check, check_stated, held_out_placements, mixed, plan_check, ArtifactCheck, MixedCheck, PlacementCheck};
use twincal::calib::pipeline::{CalibOptions, Method, ModelSpec, Parametrisation};
use twincal::error::{Error, Result};
use twincal::sim::scenario::Scenario;

/// The cases: (label, scenario file).
const CASES: [Case; 3] = [
    ("IRB 120, two sockets 50 mm apart, three placements, 30 seatings per socket", "irb120_sockets"),
    ("UR10, the same plate and seatings", "ur10_sockets"),
    ("Barrett WAM (7 joints), the same plate and seatings", "wam_sockets"),
];

/// The artifact's variants: (label, edit of the scenario's text). The scenarios' artifact is
/// printed in PLA with its second socket 0.01 mm off and seated 1 K above the temperature it
/// was made at, the ball off-centre by 0.01 mm per coordinate.
const VARIANTS: [Variant; 3] = [
    (
        "exact (as designed, at 20 °C, seated dead centre)",
        &[
            ("made_error_mm = [[0.0, 0.0], [0.01, 0.0]]", "made_error_mm = [[0.0, 0.0], [0.0, 0.0]]"),
            ("expansion_ppm_per_k = 68.0", "expansion_ppm_per_k = 0.0"),
            ("seat_std_mm = 0.01", "seat_std_mm = 0.0"),
        ],
    ),
    (
        "seated within 0.01 mm, the artifact exact",
        &[
            ("made_error_mm = [[0.0, 0.0], [0.01, 0.0]]", "made_error_mm = [[0.0, 0.0], [0.0, 0.0]]"),
            ("expansion_ppm_per_k = 68.0", "expansion_ppm_per_k = 0.0"),
        ],
    ),
    ("as made: spacing 0.01 mm long, PLA 1 K warm, seated within 0.01 mm", &[]),
];

/// The scenario `file` (its text edited by `edits`), its robot and the calibration's options.
pub(super) fn load_case(dir: &Path, file: &str, edits: &[(&str, &str)]) -> Result<(Scenario, twincal::robot::Robot, CalibOptions)> {
    let path = dir.join(format!("{file}.toml"));
    let mut text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    for (from, to) in edits {
        if !text.contains(from) {
            return Err(Error::Invalid(format!("{file}.toml: the benchmark's variant expects '{from}'")));
        }
        text = text.replace(from, to);
    }
    let s = Scenario::from_toml(&text, file)?;
    let robot = s.load_robot(Some(dir))?;
    let opts = CalibOptions::new(ModelSpec::Nominal { robot: Box::new(robot.clone()), parametrisation: Parametrisation::Hayati }, Method::LM);
    Ok((s, robot, opts))
}

/// A case: its label and scenario file.
pub(super) type Case = (&'static str, &'static str);
/// A variant: its label and the edits of the scenario's text.
pub(super) type Variant = (&'static str, &'static [(&'static str, &'static str)]);

/// The table's rows: every case under every variant over `seeds` seeds ([`check`]), the
/// artifact's arm against the nominal and a tracker calibration from as many rows.
pub(super) fn rows(dir: &Path, seeds: u64, cases: &[Case], variants: &[Variant]) -> Result<()> {
    for ((label, file), (variant, edits)) in cases.iter().flat_map(|c| variants.iter().map(move |v| (c, v))) {
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

/// Runs every case over `seeds` seeds and prints the table.
pub fn bench_sockets(seeds: u64) -> Result<()> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    println!("# A ball in sockets on the twin ({seeds} seeds): calibrated from the seated rows alone, judged on 100 tracker points no fit saw after registering the tracker on 200 others; |Δp| RMS over the points, mm, mean ± sd over seeds\n");
    println!("| case | artifact | seated rows (train) | socket rows' test RMSE | nominal | sockets | tracker, as many rows | sockets / tracker (worst seed) | calibration time (median) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    rows(dir, seeds, &CASES, &VARIANTS)?;
    beside(dir, seeds)?;
    with_faces(dir, seeds)?;
    held_out(dir, seeds)?;
    planned(dir, seeds)
}

/// Seatings planned, then seated on the twin ([`plan_check`]), against random sets of as many.
const PLANNED: usize = 24;
/// Random sets per seed.
const RANDOM_SETS: usize = 10;

/// `plan` for the IRB 120's plate (the printed one as made) verified by seating on the twin: the
/// planned seatings and random sets of as many from the same draws, each calibrated alone and
/// judged on the tracker points.
fn planned(dir: &Path, seeds: u64) -> Result<()> {
    println!("\n# {PLANNED} seatings planned (`plan --scenario irb120_sockets.toml --poses {PLANNED}`) and seated on the twin ({seeds} seeds), against {RANDOM_SETS} random sets of {PLANNED} of its candidates seated the same way (as many in each socket): held-out tracker points' |Δp| RMS, mm\n");
    println!("| seed | planned | random, median | random, best | random sets worse than the plan | seatings the true arm could not make (planned, random) |");
    println!("|---|---|---|---|---|---|");
    let (s0, robot, opts) = load_case(dir, "irb120_sockets", &[])?;
    let mut ratios = Vec::new();
    for seed in 1..=seeds {
        let popts = twincal::plan::PlanOptions { n: PLANNED, candidates: 600, seed, ..Default::default() };
        let c = plan_check(&s0, &robot, &popts, &opts, RANDOM_SETS)?;
        let mut r = c.random_mm.clone();
        r.sort_by(f64::total_cmp);
        let median = twincal::stats::median(&r);
        ratios.push(c.planned_mm / median);
        println!(
            "| {seed} | {:.4} | {median:.4} | {:.4} | {} of {} | {}, {} |",
            c.planned_mm,
            r[0],
            r.iter().filter(|v| **v > c.planned_mm).count(),
            r.len(),
            c.planned_skipped,
            c.random_skipped
        );
    }
    println!("\nplanned / random median: median {:.2}, worst {:.2}", twincal::stats::median(&ratios), ratios.iter().copied().fold(0.0, f64::max));
    Ok(())
}

/// A plate beside the block: its label, the edits of the scenario's text, and the stated
/// uncertainties of the plate's spacing and the block's step (mm).
type Plate = (&'static str, &'static [(&'static str, &'static str)], [Option<f64>; 2]);

/// The printed plate and a steel block's faces touched by the same ball, in one fit, beside
/// each alone (`irb120_sockets_planes`: the plate as made, the block's 25 mm step exact).
fn with_faces(dir: &Path, seeds: u64) -> Result<()> {
    println!("\n# Sockets and faces in one fit ({seeds} seeds; one ball seated in the printed plate as made, then touching a steel block's four faces at three places): held-out tracker points' |Δp| RMS, mm, mean ± sd over seeds\n");
    println!("| arm | plate | rows (train) | nominal | sockets alone | faces alone | sockets + faces | tracker, as many rows as both |");
    println!("|---|---|---|---|---|---|---|---|");
    let exact: &'static [(&str, &str)] = &[
        ("made_error_mm = [[0.0, 0.0], [0.01, 0.0]]", "made_error_mm = [[0.0, 0.0], [0.0, 0.0]]"),
        ("expansion_ppm_per_k = 68.0", "expansion_ppm_per_k = 0.0"),
    ];
    let plates: [Plate; 3] = [
        ("as made, stated as designed (spacing 0.01 mm long, 1 K warm)", &[], [None, None]),
        ("as made, stated as designed ± 0.02 mm, the block's step ± 0.001 mm", &[], [Some(0.02), Some(0.001)]),
        ("exact (seated within 0.01 mm)", exact, [None, None]),
    ];
    for (plate, edits, sd) in plates {
        let (s0, robot, opts) = load_case(dir, "irb120_sockets_planes", edits)?;
        let run = |f: &dyn Fn(Scenario) -> Scenario| -> Result<Vec<ArtifactCheck>> {
            (1..=seeds)
                .map(|seed| {
                    let s = f(Scenario { seed, ..s0.clone() });
                    // (The faces alone state the step only.)
                    let sd: &[Option<f64>] = if s.sockets.is_none() { &sd[1..] } else { &sd };
                    check_stated(&s, &robot, &opts, sd)
                })
                .collect()
        };
        let sockets = run(&|s| Scenario { planes: None, ..s })?;
        let faces = run(&|s| Scenario { sockets: None, ..s })?;
        let both = run(&|s| s)?;
        let col = |all: &[ArtifactCheck], f: &dyn Fn(&ArtifactCheck) -> f64| {
            let (m, sd) = mean_sd(&all.iter().map(f).collect::<Vec<_>>());
            format!("{m:.4} ± {sd:.4}")
        };
        println!(
            "| IRB 120 | {plate} | {} | {} | {} | {} | {} | {} |",
            both[0].artifact_rows,
            col(&both, &|c| c.nominal_mm),
            col(&sockets, &|c| c.artifact_mm),
            col(&faces, &|c| c.artifact_mm),
            col(&both, &|c| c.artifact_mm),
            col(&both, &|c| c.tracker_mm)
        );
    }
    Ok(())
}

/// Tracker points beside the seated rows, in one fit.
const POINTS: usize = 20;

/// Each arm's printed plate with [`POINTS`] tracker points beside it, in one fit.
fn beside(dir: &Path, seeds: u64) -> Result<()> {
    println!("\n# Sockets and {POINTS} tracker points in one fit ({seeds} seeds; the plate as made): held-out tracker points' |Δp| RMS, mm, mean ± sd over seeds; the first placement's spacing as fitted against as made (the stated one is 50 mm)\n");
    println!("| arm | sockets alone | sockets + {POINTS} points | spacing fitted - made (mean abs) |");
    println!("|---|---|---|---|");
    for (label, file) in CASES {
        let (s0, robot, opts) = load_case(dir, file, &[])?;
        let all: Vec<MixedCheck> = (1..=seeds).map(|seed| mixed(&Scenario { seed, ..s0.clone() }, &robot, &opts, POINTS)).collect::<Result<_>>()?;
        let col = |f: &dyn Fn(&MixedCheck) -> f64| {
            let (m, sd) = mean_sd(&all.iter().map(f).collect::<Vec<_>>());
            format!("{m:.4} ± {sd:.4}")
        };
        let off = all.iter().map(|c| (c.spacing_fitted_mm - c.spacing_made_mm).abs()).sum::<f64>() / all.len().max(1) as f64;
        println!("| {} | {} | {} | {off:.4} |", label.split(',').next().unwrap_or(label), col(&|c| c.artifact_mm), col(&|c| c.mixed_mm));
    }
    Ok(())
}

/// Each placement trained on alone, every other one judged: socket scatter and spacing error.
fn held_out(dir: &Path, seeds: u64) -> Result<()> {
    println!("\n# A held-out placement ({seeds} seeds): calibrated on one placement's rows alone, judged on each other placement by each socket's scatter (RMS distance of the predicted ball centres from their mean) and the spacing error (|distance between the socket means - 50 mm|); mean over seeds and sockets, mm\n");
    println!("| arm | trained on | judged | nominal: scatter | twincal: scatter | nominal: spacing error | twincal: spacing error |");
    println!("|---|---|---|---|---|---|---|");
    for (label, file) in CASES {
        let (s0, robot, opts) = load_case(dir, file, &[])?;
        let all: Vec<PlacementCheck> =
            (1..=seeds).map(|seed| held_out_placements(&Scenario { seed, ..s0.clone() }, &robot, &opts)).collect::<Result<Vec<_>>>()?.concat();
        let arm = label.split(',').next().unwrap_or(label);
        let mut pairs: Vec<(String, String)> = all.iter().map(|c| (c.trained_on.clone(), c.judged.clone())).collect();
        pairs.dedup();
        pairs.sort();
        pairs.dedup();
        for (t, j) in pairs {
            let of = |model: &str, f: &dyn Fn(&PlacementCheck) -> f64| {
                let v: Vec<f64> = all.iter().filter(|c| c.trained_on == t && c.judged == j && c.model == model).map(f).collect();
                v.iter().sum::<f64>() / v.len().max(1) as f64
            };
            let scatter = |c: &PlacementCheck| c.scatter_mm.iter().map(|(_, v)| v).sum::<f64>() / c.scatter_mm.len().max(1) as f64;
            let spacing = |c: &PlacementCheck| c.spacing_error_mm;
            println!(
                "| {arm} | {t} | {j} | {:.4} | {:.4} | {:.4} | {:.4} |",
                of("nominal", &scatter),
                of("twincal", &scatter),
                of("nominal", &spacing),
                of("twincal", &spacing)
            );
        }
    }
    Ok(())
}
