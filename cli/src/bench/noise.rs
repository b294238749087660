//! `twincal bench noise-model`: what modelling the joint angles' logging error
//! ([`twincal::calib::fit::noise_model::remove_logging_error`], `calibrate --noise-model auto`) changes in
//! lm, dsade-gkan and pso-ekf-awnn, against the same methods taking the rows as independent
//! (`--noise-model off`), on real-like acquisitions of the twin: the IRB 120 with its geometric
//! errors read by a draw-wire, in sweeps of 20 poses, the angles logged at 0.1°, with glitch runs
//! ([`twincal::diagnose::hidden::realistic`]).
//!
//! Judged on held-out whole sweeps (a quarter of the rows): the measured test RMSE an engineer
//! sees, and the true error, the calibrated model's reading at the commanded (unrounded) angles
//! against the twin's noise-free reading there. Medians over seeds, and the median over seeds of
//! each seed's ratio auto/off; each run's time.

use std::time::Instant;
use twincal::calib::pipeline::{calibrate, CalibOptions, Method, ModelSpec};
use twincal::dataset::{Dataset, Row};
use twincal::error::Result;
use twincal::sim::generate::{generate as run_generate, Silent};
use twincal::stats::median;

/// The methods compared (their `--method` names).
pub const METHODS: [&str; 3] = ["lm", "dsade-gkan", "pso-ekf-awnn"];

/// One calibration of the benchmark.
struct Run {
    test_mm: f64,
    true_mm: f64,
    seconds: f64,
    removed_mm: f64,
}

/// Calibrates `data` with `method` and the noise model `choice`, judged on its held-out blocks
/// against the twin's noise-free readings `truth` at the commanded angles `q_cmd` (degrees).
fn run(data: &Dataset, q_cmd: &[Vec<f64>], truth: &[f64], method: &str, choice: twincal::calib::fit::noise_model::NoiseChoice, seed: u64) -> Result<Run> {
    let mut opts =
        CalibOptions::new(ModelSpec::nominal(twincal::robot::Robot::irb120(), twincal::calib::pipeline::Parametrisation::Hayati), Method::parse(method)?);
    opts.split.test_fraction = Some(0.25);
    opts.seed = seed;
    opts.floor.noise_model = choice;
    let t0 = Instant::now();
    let r = calibrate(data, None, &opts)?;
    let seconds = t0.elapsed().as_secs_f64();
    let err: Vec<f64> = r.provenance.test_rows.iter().map(|&i| r.predict_mm(&q_cmd[i]) - truth[i]).collect();
    let true_mm = (err.iter().map(|e| e * e).sum::<f64>() / err.len().max(1) as f64).sqrt();
    Ok(Run {
        test_mm: r.evaluation.metrics.test_after.as_ref().map_or(f64::NAN, |m| m.rmse),
        true_mm,
        seconds,
        removed_mm: r.solve.noise_model.as_ref().and_then(|n| n.removed_rms_mm).unwrap_or(0.0),
    })
}

/// `twincal bench noise-model --seeds N`: per seed a realistic acquisition, each method with
/// and without the noise model; prints each seed's line and the medians.
pub fn bench_noise_model(seeds: u64) -> Result<()> {
    use twincal::calib::fit::noise_model::NoiseChoice::{Auto, Off};
    println!("bench noise-model: IRB 120 geometric errors, draw-wire, sweeps of 20 poses, angles logged at 0.1 deg, glitch runs, 400 poses;");
    println!("  held-out whole sweeps (25 %); 'true' is the model's reading at the commanded angles against the twin's noise-free reading");
    // Per method: (auto, off) runs over seeds.
    let mut all: Vec<Vec<(Run, Run)>> = METHODS.iter().map(|_| Vec::new()).collect();
    for seed in 1..=seeds {
        let (s, robot) = twincal::diagnose::hidden::realistic(40_000 + seed, 1)?;
        let g = run_generate(&s, &robot, &Silent)?;
        let data = Dataset { rows: g.dataset.rows.iter().map(|r| Row { split: None, ..r.clone() }).collect(), source: g.dataset.source.clone() };
        let q_cmd: Vec<Vec<f64>> = g.truth.poses.iter().map(|p| p.q_cmd_deg.clone()).collect();
        let truth: Vec<f64> = g.truth.poses.iter().map(|p| p.length_noise_free_mm).collect();
        for (k, m) in METHODS.iter().enumerate() {
            let on = run(&data, &q_cmd, &truth, m, Auto, seed)?;
            let off = run(&data, &q_cmd, &truth, m, Off, seed)?;
            println!(
                "  seed {:5} {m:13} true {:.4} -> {:.4} mm, test {:.4} -> {:.4} mm (off -> auto; logging error taken out: RMS {:.4} mm), {:.1} / {:.1} s",
                40_000 + seed,
                off.true_mm,
                on.true_mm,
                off.test_mm,
                on.test_mm,
                on.removed_mm,
                off.seconds,
                on.seconds
            );
            all[k].push((on, off));
        }
    }
    println!("medians over {seeds} seeds (off -> auto; ratio: the median of each seed's auto/off):");
    for (m, runs) in METHODS.iter().zip(&all) {
        let med = |f: &dyn Fn(&(Run, Run)) -> f64| median(&runs.iter().map(f).collect::<Vec<_>>());
        println!(
            "  {m:13} true {:.4} -> {:.4} mm (ratio {:.3}, better on {}/{} seeds), test {:.4} -> {:.4} mm (ratio {:.3}), time {:.1} -> {:.1} s (ratio {:.2})",
            med(&|r| r.1.true_mm),
            med(&|r| r.0.true_mm),
            med(&|r| r.0.true_mm / r.1.true_mm),
            runs.iter().filter(|r| r.0.true_mm < r.1.true_mm).count(),
            runs.len(),
            med(&|r| r.1.test_mm),
            med(&|r| r.0.test_mm),
            med(&|r| r.0.test_mm / r.1.test_mm),
            med(&|r| r.1.seconds),
            med(&|r| r.0.seconds),
            med(&|r| r.0.seconds / r.1.seconds),
        );
    }
    Ok(())
}
