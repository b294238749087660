//! `twincal bench compensate`: compensation verified on executed poses over seeds — the twin
//! calibrated on its own dataset, then the nominal and the compensated commands for 100 unseen
//! targets executed on it ([`twincal::compensate::verify`]); AP (ISO 9283 position accuracy,
//! one cycle) before and after, for geometric and non-geometric scenarios, cable and tracker,
//! and the time `compensate` takes per 10 000 targets against its 1 s target.

use std::path::Path;
use std::time::Instant;
use twincal::calib::effects::EffectKind;
use twincal::calib::pipeline::{CalibOptions, Method, ModelSpec, Parametrisation};
use twincal::compensate::verify::{verify_seed, SeedCheck};
use twincal::error::Result;
use twincal::sim::scenario::Scenario;

/// Compliance under a 3 kg payload, added to a scenario before its `[sensor]` (also the
/// programs' bench's).
pub(crate) const COMPLIANCE: &str =
    "[effects.compliance]\nstiffness_nm_per_rad = [1.5e5, 2.0e4, 3.0e4, 3.0e4, 3.0e4, 2.0e4]\n\n[effects.payload]\nmass_kg = 3.0\ncom_mm = [40.0, 0.0, 60.0]\n\n";

/// The scenarios: (label, scenario file, text added before `[sensor]`, whether the calibration
/// models the compliance with the stated payload, whether the targets are poses).
const CASES: [(&str, &str, &str, bool, bool); 7] = [
    ("IRB 120, cable, geometric", "irb120_geometric", "", false, false),
    ("IRB 120, tracker, geometric", "irb120_tracker", "", false, false),
    ("IRB 120, tracker, compliance under 3 kg", "irb120_tracker", COMPLIANCE, true, false),
    ("IRB 120, cable, compliance under 3 kg", "irb120_geometric", COMPLIANCE, true, false),
    ("IRB 120, tracker, compliance under 3 kg, calibrated geometric only", "irb120_tracker", COMPLIANCE, false, false),
    ("UR10, 6-D probe, geometric, pose targets", "ur10_pose", "", false, true),
    ("UR10, 6-D probe, compliance under 3 kg, pose targets", "ur10_pose", COMPLIANCE, true, true),
];

/// Mean and sample standard deviation.
pub(crate) fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    (m, (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt())
}

/// A case's scenario (the file `dir/file.toml` with `extra` added before its `[sensor]`), robot
/// and calibration options (LM, Hayati; with `model_it`, compliance at every joint under the
/// scenario's payload). Also the programs' bench's.
pub(crate) fn case(dir: &Path, file: &str, extra: &str, model_it: bool) -> Result<(Scenario, twincal::robot::Robot, CalibOptions)> {
    let path = dir.join(format!("{file}.toml"));
    let text = std::fs::read_to_string(&path).map_err(|e| twincal::error::Error::io(&path, e))?.replacen("[sensor]", &format!("{extra}[sensor]"), 1);
    let s = Scenario::from_toml(&text, file)?;
    let robot = s.load_robot(Some(dir))?;
    let mut opts = CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM);
    if model_it {
        opts.effects = (0..robot.dof()).map(|j| (EffectKind::Compliance, Some(j))).collect();
        opts.loads.joints.payload = s.effects.payload.clone();
    }
    Ok((s, robot, opts))
}

/// Runs every case over `seeds` seeds and prints the table.
pub fn bench_compensate(seeds: u64) -> Result<()> {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios"));
    println!("# Compensation verified on executed poses ({seeds} seeds, 100 unseen targets each, AP of one cycle in mm: mean over targets, then mean ± sd over seeds)\n");
    println!("(pose targets: also the angle between each target's orientation and the attained one, degrees, mean over targets)\n");
    println!(
        "| scenario | calibration test RMSE | nominal AP | nominal AP max | predicted nominal AP | compensated AP | compensated AP max | nominal angle ° | compensated angle ° | targets judged |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for (label, file, extra, model_it, poses) in CASES {
        let (s, robot, opts) = case(dir, file, extra, model_it)?;
        let checks: Vec<SeedCheck> = (1..=seeds).map(|seed| verify_seed(&s, &robot, &opts, 100, seed, poses)).collect::<Result<_>>()?;
        let col = |f: &dyn Fn(&SeedCheck) -> f64| {
            let (m, sd) = mean_sd(&checks.iter().map(f).collect::<Vec<_>>());
            format!("{m:.4} ± {sd:.4}")
        };
        let angle = |f: &dyn Fn(&(twincal::stats::metrics::ErrorStats, twincal::stats::metrics::ErrorStats)) -> f64| match poses {
            true => col(&|c| c.orientation_deg.as_ref().map_or(f64::NAN, f)),
            false => "–".to_string(),
        };
        println!(
            "| {label} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            col(&|c| c.calibration_test_rmse_mm),
            col(&|c| c.nominal_ap_mm.mean),
            col(&|c| c.nominal_ap_mm.max),
            col(&|c| c.predicted_nominal_ap_mm.mean),
            col(&|c| c.compensated_ap_mm.mean),
            col(&|c| c.compensated_ap_mm.max),
            angle(&|o| o.0.mean),
            angle(&|o| o.1.mean),
            checks.iter().map(|c| c.judged).sum::<usize>()
        );
    }
    speed()
}

/// `compensate` on 10 000 targets of the embedded scenario's calibration: median of 5 runs
/// against the 1 s target.
fn speed() -> Result<()> {
    let s = Scenario::from_toml(twincal::sim::scenario::DEFAULT_SCENARIO, twincal::sim::scenario::DEFAULT_SCENARIO_NAME)?;
    let robot = s.load_robot(None)?;
    let g = twincal::sim::generate::generate(&s, &robot, &twincal::sim::generate::Silent)?;
    let r = twincal::calib::pipeline::calibrate(&g.dataset, None, &CalibOptions::new(ModelSpec::nominal(robot.clone(), Parametrisation::Hayati), Method::LM))?;
    let x_nom = twincal::compensate::nominal_x(&r);
    let c = twincal::compensate::Compensator::new(&r, &x_nom, r.torque_model.clone(), 0.001, 0.001)?;
    let targets: Vec<twincal::compensate::Target> = (0..10_000)
        .map(|i| {
            twincal::compensate::Target::Point(c.predicted(&g.dataset.rows[i % g.dataset.rows.len()].q_deg.iter().map(|d| d.to_radians()).collect::<Vec<_>>()))
        })
        .collect();
    let mut times: Vec<f64> = (0..5)
        .map(|_| {
            let t = Instant::now();
            let out = c.compensate(&targets);
            std::hint::black_box(out.len());
            t.elapsed().as_secs_f64()
        })
        .collect();
    times.sort_by(f64::total_cmp);
    println!(
        "\ncompensate, 10 000 targets of the embedded scenario's calibration on {} threads: median {:.3} s of 5 runs (target < 1 s)",
        rayon::current_num_threads(),
        times[2]
    );
    Ok(())
}
