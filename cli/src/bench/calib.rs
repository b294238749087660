//! `twincal bench calib`: LM's speed, accuracy over seeds against the truth, the untuned
//! methods on other spreads and noise, and the HSR-RobotCali pool.

use std::path::Path;
use std::time::Instant;
use twincal::calib::problem::ReadingFit;
use twincal::error::{Error, Result};
use twincal::optim::LeastSquares;
use twincal::sim::generate::{generate as run_generate, write_outputs, Silent};
use twincal::sim::scenario::Scenario;
use twincal::stats::median;

/// Seconds of one residual + Jacobian evaluation of `fit` at `x` (the unit an LM run is counted in).
fn evaluation_s(fit: &ReadingFit, x: &[f64]) -> f64 {
    let t0 = Instant::now();
    let mut j = nalgebra::DMatrix::zeros(fit.n_residuals(), fit.model.n_params());
    fit.jacobian(x, &mut j);
    let mut r = vec![0.0; fit.n_residuals()];
    fit.residuals(x, &mut r);
    std::hint::black_box((&j, &r));
    t0.elapsed().as_secs_f64()
}

/// A step run on one of the benchmark's dataset folders (the `compare` command, given by the caller).
pub type OnDataset<'a> = &'a dyn Fn(&Path) -> Result<()>;

/// `twincal bench calib`: the calibration core's targets, measured. `compare`, when given, runs
/// on a 400-pose dataset folder of the benchmark (the caller's full method comparison).
pub fn bench_calib(repeat: usize, seeds: u64, compare: Option<OnDataset>) -> Result<()> {
    use rayon::prelude::*;
    use twincal::calib::run::{calibrate as run, CalibOptions, Method, ModelSpec, TruthFile};
    let (base, robot) =
        Scenario::from_toml(include_str!("../../../scenarios/irb120_geometric.toml"), "irb120_geometric").and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    let spec = ModelSpec::Nominal { robot: Box::new(robot.clone()), parametrisation: "hayati".into() };
    // Removed on every exit path (by its Drop).
    let tmp_dir = tempfile::Builder::new().prefix("twincal-bench-").tempdir().map_err(|e| Error::create_dir(std::env::temp_dir(), e))?;
    let tmp = tmp_dir.path();
    let gen = |seed: u64, poses: usize, test: usize| -> Result<(twincal::dataset::Dataset, TruthFile)> {
        let mut s = base.clone();
        s.seed = seed;
        s.sampling.poses = poses;
        s.sampling.test = test;
        let g = run_generate(&s, &robot, &Silent)?;
        let dir = tmp.join(format!("s{seed}-{poses}"));
        write_outputs(&g, &dir)?;
        let truth = TruthFile::find(&dir)?.ok_or_else(|| Error::Invalid("truth missing".into()))?;
        Ok((g.dataset, truth))
    };

    // 1. LM speed on 500 training poses: the LM alone from the pipeline's prepared start (the
    // draw-wire placed, its identifiable set), against one residual + Jacobian evaluation; and
    // the whole calibrate (the placement search over the cable's exit point, the outlier screen,
    // identifiability, covariance, the truth comparison).
    let (ds, truth) = gen(base.seed, 600, 100)?;
    let opts = CalibOptions::new(spec.clone(), Method::Lm);
    let prepared = twincal::calib::run::prepare(&ds, &opts, false)?;
    let fit = ReadingFit { model: &prepared.model, data: &prepared.split.train };
    let lm = twincal::calib::methods::LmSolver::default().lm;
    let (mut lm_t, mut ev_t, mut whole_t, mut iters) = (Vec::new(), Vec::new(), Vec::new(), 0);
    for _ in 0..repeat.max(5) {
        let t0 = Instant::now();
        let rep = lm.minimize(&fit, &prepared.model.nominal, &prepared.id.fixed_mask, &mut twincal::optim::NoObserver);
        lm_t.push(t0.elapsed().as_secs_f64());
        iters = rep.iterations;
        ev_t.push(evaluation_s(&fit, &prepared.model.nominal));
        whole_t.push(run(&ds, Some(&truth), &opts)?.wall_time_s);
    }
    let (t_lm, t_j) = (median(&lm_t), median(&ev_t));
    println!("calibration benchmark");
    println!(
        "  LM, {} training poses      : {:8.2} ms median (target < 20 ms), {iters} iterations; one residual+Jacobian evaluation {:.3} ms -> LM = {:.1} evaluations; whole calibrate {:.1} ms",
        fit.data.len(),
        t_lm * 1e3,
        t_j * 1e3,
        t_lm / t_j,
        median(&whole_t) * 1e3
    );
    println!("    (the whole calibrate adds the cable's placement search, the outlier screen, identifiability, covariance and the truth comparison)");

    // 1b. The same on a laser tracker's points (three residuals a row): 1000 training poses of
    // the twin's tracker scenario. The LM alone (from the pipeline's prepared start, with its
    // identifiable set) against one residual + Jacobian evaluation, and the whole calibrate.
    let (ts, trobot) =
        Scenario::from_toml(include_str!("../../../scenarios/irb120_tracker.toml"), "irb120_tracker").and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    let mut ts = ts;
    (ts.sampling.poses, ts.sampling.test) = (1100, 100);
    let tds = run_generate(&ts, &trobot, &Silent)?.dataset;
    let topts = CalibOptions::new(ModelSpec::Nominal { robot: Box::new(trobot), parametrisation: "hayati".into() }, Method::Lm);
    let prepared = twincal::calib::run::prepare(&tds, &topts, false)?;
    let tfit = ReadingFit { model: &prepared.model, data: &prepared.split.train };
    let lm = twincal::calib::methods::LmSolver::default().lm;
    let (mut lm_t, mut ev_t, mut whole_t, mut t_iters, mut t_test) = (Vec::new(), Vec::new(), Vec::new(), 0, f64::NAN);
    for _ in 0..repeat.max(5) {
        let t0 = Instant::now();
        let rep = lm.minimize(&tfit, &prepared.model.nominal, &prepared.id.fixed_mask, &mut twincal::optim::NoObserver);
        lm_t.push(t0.elapsed().as_secs_f64());
        t_iters = rep.iterations;
        ev_t.push(evaluation_s(&tfit, &prepared.model.nominal));
        let whole = run(&tds, None, &topts)?;
        whole_t.push(whole.wall_time_s);
        t_test = whole.metrics.test_after.map(|m| m.rmse).unwrap_or(f64::NAN);
    }
    println!(
        "  LM, {} tracker points ({} residuals): {:8.2} ms median (target < 50 ms), {t_iters} iterations; one residual+Jacobian evaluation {:.3} ms -> LM = {:.1} evaluations; whole calibrate {:.1} ms; test RMSE {t_test:.4} mm per coordinate",
        tfit.data.len(),
        tfit.n_residuals(),
        median(&lm_t) * 1e3,
        median(&ev_t) * 1e3,
        median(&lm_t) / median(&ev_t),
        median(&whole_t) * 1e3
    );

    // 2. Accuracy over seeds: test RMSE against the noise floor, parameters against the truth.
    let rows: Vec<Result<(f64, usize, usize, f64)>> = (0..seeds)
        .into_par_iter()
        .map(|seed| {
            let (ds, truth) = gen(1000 + seed, 400, 100)?;
            let r = run(&ds, Some(&truth), &opts)?;
            let c = r.truth_comparison.clone().ok_or_else(|| Error::Invalid("no truth comparison".into()))?;
            Ok((r.metrics.test_after.map(|m| m.rmse).unwrap_or(f64::NAN) / truth.noise_std_mm, c.within_3_sigma, c.identifiable, c.max_abs_z))
        })
        .collect();
    let rows: Vec<(f64, usize, usize, f64)> = rows.into_iter().collect::<Result<_>>()?;
    let ratios: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let within5 = ratios.iter().filter(|r| (*r - 1.0).abs() <= 0.05).count();
    let all_in = rows.iter().filter(|r| r.1 == r.2).count();
    let total_in: usize = rows.iter().map(|r| r.1).sum();
    let total: usize = rows.iter().map(|r| r.2).sum();
    let zs: Vec<f64> = rows.iter().map(|r| r.3).collect();
    let (r_min, r_max) = ratios.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(*r), hi.max(*r)));
    println!("  irb120_geometric, {seeds} seeds (400 poses, 300/100):");
    println!("    test RMSE / noise floor   : median {:.3}, min {:.3}, max {:.3}; within 5 %: {within5}/{seeds} (sampling spread of an RMSE over 100 test poses is about ±7 %)", median(&ratios), r_min, r_max);
    println!("    identifiable within 3σ    : {total_in}/{total} parameters; every one in {all_in}/{seeds} seeds; median max |z| {:.2}", median(&zs));

    // 2b. Untuned methods: a scenario whose spreads and noise differ from the defaults (0.8 mm,
    // 0.12°, 0.15° and 0.2 mm raw noise, 20 samples); priors come from the documented tolerances
    // and the noise from the data, never from the scenario.
    let mut other = base.clone();
    other.geometry.origin_offset_std_mm = 0.8;
    other.geometry.origin_rotation_std_deg = 0.12;
    other.geometry.joint_zero_std_deg = 0.15;
    other.sensor.noise_std_mm = 0.2;
    other.sensor.samples = 20;
    let sets: Vec<(twincal::dataset::Dataset, f64)> = (0..5u64)
        .map(|i| {
            let mut s = other.clone();
            s.seed = 21 + i;
            let g = run_generate(&s, &robot, &Silent)?;
            Ok((g.dataset, g.truth.noise_std_mm))
        })
        .collect::<Result<_>>()?;
    println!("  untuned methods on other spreads and noise (5 seeds, 400 poses, floor {:.4} mm): median test RMSE / floor, time per run", sets[0].1);
    for m in Method::ALL {
        let t0 = Instant::now();
        let ratios: Vec<f64> = sets
            .par_iter()
            .map(|(ds, floor)| {
                let r = run(ds, None, &CalibOptions::new(spec.clone(), m))?;
                Ok(r.metrics.test_after.map(|t| t.rmse).unwrap_or(f64::NAN) / floor)
            })
            .collect::<Result<_>>()?;
        println!(
            "    {:<4} {:.3} (range {:.3}–{:.3}), {:.1} s per run",
            m.name(),
            median(&ratios),
            ratios.iter().cloned().fold(f64::INFINITY, f64::min),
            ratios.iter().cloned().fold(0.0, f64::max),
            t0.elapsed().as_secs_f64() / 2.5
        );
    }

    // 3. The full comparison over 30 seeds.
    if let Some(compare) = compare {
        let t0 = Instant::now();
        compare(&tmp.join(format!("s{}-400", 1000)))?;
        println!("  compare, 5 methods x 30 seeds: {:.1} s wall time", t0.elapsed().as_secs_f64());
    }

    // 4. Real data.
    let hsr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/hsr-robotcali/hsr_robotcali_pool.csv");
    if hsr.exists() {
        let ds = twincal::dataset::Dataset::load(&hsr)?;
        let mut o = CalibOptions::new(ModelSpec::Generic6r, Method::Lm);
        o.test_fraction = Some(0.2);
        let r = run(&ds, None, &o)?;
        if let (Some(rep), Some(t), Some(tt)) = (&r.repeatability, &r.metrics.test_after, &r.metrics.test_after_trimmed) {
            println!(
                "  HSR-RobotCali (generic6r, 80/20): held-out RMSE {:.4} mm, repeatability floor {:.4} mm, ratio {:.3} (target < 1.3); without the worst 1 % {:.3}; {:.1} s (bench real: the interleaved split over seeds)",
                t.rmse,
                rep.pooled_std,
                t.rmse / rep.pooled_std,
                tt.rmse / rep.pooled_std,
                r.wall_time_s
            );
        }
    } else {
        println!("  HSR-RobotCali: skipped, {} is absent", hsr.display());
    }
    drop(tmp_dir);
    Ok(())
}
