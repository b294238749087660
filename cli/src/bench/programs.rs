//! `twincal bench programs`: program filtering verified on executed programs over seeds
//! ([`twincal::controller::filter::verify`]) — per language, its arm and its twin: the program
//! as written and its filtered copy, each interpreted by a nominal controller and executed by
//! the twin's true arm, AP (ISO 9283, one cycle) of each; geometric and compliance under a
//! payload. Then the filter's speed on a 10 000-target RAPID module against its 2 s target.

use super::compensate::{case, mean_sd, COMPLIANCE};
use std::path::Path;
use std::time::Instant;
use twincal::controller::filter::verify::{verify_program, ProgramCheck};
use twincal::controller::Language;
use twincal::error::Result;

/// The cases: (label, language, scenario, text added before `[sensor]`, whether the
/// calibration models the compliance with the stated payload).
const CASES: [(&str, Language, &str, &str, bool); 6] = [
    ("IRB 120, RAPID, geometric", Language::Rapid, "irb120_tracker", "", false),
    ("IRB 120, RAPID, compliance under 3 kg", Language::Rapid, "irb120_tracker", COMPLIANCE, true),
    ("UR10, URScript, geometric", Language::Urscript, "ur10_tracker", "", false),
    ("UR10, URScript, compliance under 3 kg", Language::Urscript, "ur10_tracker", COMPLIANCE, true),
    ("KUKA-like (kr6.urdf), KRL, geometric", Language::Krl, "kr6_tracker", "", false),
    ("KUKA-like (kr6.urdf), KRL, compliance under 3 kg", Language::Krl, "kr6_tracker", COMPLIANCE, true),
];

/// Targets per program.
const TARGETS: usize = 120;

/// Runs every case over `seeds` seeds and prints the table, then the speed.
pub fn bench_programs(seeds: u64, repeat: usize) -> Result<()> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    println!("# Programs filtered and executed on the twin ({seeds} seeds, {TARGETS} unseen targets each in a work object with a tool; AP of one cycle in mm after registering each program's attained points: mean over targets, then mean ± sd over seeds; a target left as written is executed as written)\n");
    println!("| arm, language, twin | calibration test RMSE | AP as written | AP as written, max | AP filtered | AP filtered, max | AP of the targets filtered | targets filtered | left as written | judged |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (label, lang, file, extra, model_it) in CASES {
        let (s, robot, opts) = case(dir, file, extra, model_it)?;
        let checks: Vec<ProgramCheck> = (1..=seeds).map(|seed| verify_program(&s, &robot, &opts, lang, TARGETS, seed)).collect::<Result<_>>()?;
        let col = |f: &dyn Fn(&ProgramCheck) -> f64| {
            let (m, sd) = mean_sd(&checks.iter().map(f).collect::<Vec<_>>());
            format!("{m:.4} ± {sd:.4}")
        };
        let sum = |f: &dyn Fn(&ProgramCheck) -> usize| checks.iter().map(f).sum::<usize>();
        println!(
            "| {label} | {} | {} | {} | {} | {} | {} | {} of {} | {} | {} |",
            col(&|c| c.calibration_test_rmse_mm),
            col(&|c| c.original_ap_mm.mean),
            col(&|c| c.original_ap_mm.max),
            col(&|c| c.filtered_ap_mm.mean),
            col(&|c| c.filtered_ap_mm.max),
            col(&|c| c.filtered_only_ap_mm.mean),
            sum(&|c| c.filtered),
            sum(&|c| c.targets),
            sum(&|c| c.left),
            sum(&|c| c.judged)
        );
    }
    speed(dir, repeat)
}

/// The filter on a RAPID module of 10 000 targets (the IRB 120 tracker twin's calibration):
/// median of `repeat` runs against the 2 s target.
fn speed(dir: &Path, repeat: usize) -> Result<()> {
    use twincal::controller::filter::{filter_program, sample::SampleProgram, FilterOptions, Setup};
    let (s, robot, opts) = case(dir, "irb120_tracker", "", false)?;
    let g = twincal::sim::generate::generate(&s, &robot, &twincal::sim::generate::Silent)?;
    let r = twincal::calib::pipeline::calibrate(&g.dataset, None, &opts)?;
    let x_nom = twincal::compensate::nominal_x(&r);
    let c = twincal::compensate::Compensator::new(&r, &x_nom, None, 0.001, 0.001)?;
    let setup = Setup::new(&r, &x_nom, Some(&robot));
    let tool = setup.probe_tool();
    let targets = (0..10_000)
        .map(|i| {
            let q: Vec<f64> = g.dataset.rows[i % g.dataset.rows.len()].q_deg.iter().map(|d| d.to_radians()).collect();
            let (p, rot) = c.predicted_pose(&q);
            (setup.program_pose(&p, &rot) * tool, setup.config(twincal::controller::filter::Layout::RapidPose, &q))
        })
        .collect();
    let prog = SampleProgram { name: "twc_speed".into(), tool, frame: nalgebra::Isometry3::identity(), targets, home: vec![0.0; 6] };
    let (files, _) = prog.write(Language::Rapid);
    let mut times = Vec::new();
    let mut filtered = 0;
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        let f = filter_program(&c, &setup, Language::Rapid, &files, &[], &FilterOptions::default())?;
        times.push(t.elapsed().as_secs_f64());
        filtered = f.targets.iter().filter(|t| t.outcome == twincal::controller::filter::Outcome::Filtered).count();
    }
    times.sort_by(f64::total_cmp);
    println!(
        "\nfilter, a RAPID module of 10 000 targets ({} bytes; {filtered} filtered) on {} threads: median {:.3} s of {} runs (target < 2 s)",
        files[0].text.len(),
        rayon::current_num_threads(),
        times[times.len() / 2],
        times.len()
    );
    Ok(())
}
