//! `twincal bench calib`: LM's speed, accuracy over seeds against the truth, the untuned
//! methods on other spreads and noise, and the HSR-RobotCali pool.

use std::path::Path;
use std::time::Instant;
use twincal::calib::fit::ReadingFit;
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

/// LM's speed on a dataset: the LM alone from the pipeline's prepared start (its identifiable
/// set), against one residual + Jacobian evaluation, and the whole calibrate.
struct LmSpeed {
    /// Training rows and residuals.
    rows: usize,
    residuals: usize,
    /// Medians, s.
    lm_s: f64,
    evaluation_s: f64,
    whole_s: f64,
    iterations: usize,
    /// The whole calibrate's test RMSE (mm per value), last run.
    test_rmse: f64,
}

fn lm_speed(
    ds: &twincal::dataset::Dataset,
    truth: Option<&twincal::calib::pipeline::TruthFile>,
    opts: &twincal::calib::pipeline::CalibOptions,
    repeat: usize,
) -> Result<LmSpeed> {
    let prepared = twincal::calib::pipeline::prepare(ds, opts, opts.method.needs())?;
    let fit = ReadingFit { model: &prepared.model, data: &prepared.split.train };
    let lm = twincal::calib::methods::LmSolver::default().lm;
    let (mut lm_t, mut ev_t, mut whole_t, mut iterations, mut test_rmse) = (Vec::new(), Vec::new(), Vec::new(), 0, f64::NAN);
    for _ in 0..repeat.max(5) {
        let t0 = Instant::now();
        let rep = lm.minimize(&fit, &prepared.model.nominal, &prepared.id.fixed_mask, &mut twincal::optim::NoObserver);
        lm_t.push(t0.elapsed().as_secs_f64());
        iterations = rep.iterations;
        ev_t.push(evaluation_s(&fit, &prepared.model.nominal));
        let whole = twincal::calib::pipeline::calibrate(ds, truth, opts)?;
        whole_t.push(whole.provenance.wall_time_s);
        test_rmse = whole.evaluation.metrics.test_after.map(|m| m.rmse).unwrap_or(f64::NAN);
    }
    Ok(LmSpeed {
        rows: fit.data.len(),
        residuals: fit.n_residuals(),
        lm_s: median(&lm_t),
        evaluation_s: median(&ev_t),
        whole_s: median(&whole_t),
        iterations,
        test_rmse,
    })
}

/// `twincal bench calib`: the calibration core's targets, measured. `compare`, when given, runs
/// on a 400-pose dataset folder of the benchmark (the caller's full method comparison).
pub fn bench_calib(repeat: usize, seeds: u64, compare: Option<OnDataset>) -> Result<()> {
    use twincal::calib::pipeline::{CalibOptions, Method, ModelSpec, TruthFile};
    let (base, robot) =
        Scenario::from_toml(include_str!("../../../scenarios/irb120_geometric.toml"), "irb120_geometric").and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    let spec = ModelSpec::nominal(robot.clone(), twincal::calib::pipeline::Parametrisation::Hayati);
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

    // 1. LM speed on 500 training poses of the draw-wire (the whole calibrate adds the placement
    // search over the cable's exit point, the outlier screen, identifiability, covariance, the
    // truth comparison).
    let (ds, truth) = gen(base.seed, 600, 100)?;
    let opts = CalibOptions::new(spec.clone(), Method::LM);
    let c = lm_speed(&ds, Some(&truth), &opts, repeat)?;
    println!("calibration benchmark");
    println!(
        "  LM, {} training poses      : {:8.2} ms median (target < 20 ms), {} iterations; one residual+Jacobian evaluation {:.3} ms -> LM = {:.1} evaluations; whole calibrate {:.1} ms",
        c.rows,
        c.lm_s * 1e3,
        c.iterations,
        c.evaluation_s * 1e3,
        c.lm_s / c.evaluation_s,
        c.whole_s * 1e3
    );
    println!("    (the whole calibrate adds the cable's placement search, the outlier screen, identifiability, covariance and the truth comparison)");

    // 1b. The same on a laser tracker's points (three residuals a row): 1000 training poses of
    // the twin's tracker scenario.
    let (mut ts, trobot) =
        Scenario::from_toml(include_str!("../../../scenarios/irb120_tracker.toml"), "irb120_tracker").and_then(|s| s.load_robot(None).map(|r| (s, r)))?;
    (ts.sampling.poses, ts.sampling.test) = (1100, 100);
    let tds = run_generate(&ts, &trobot, &Silent)?.dataset;
    let topts = CalibOptions::new(ModelSpec::nominal(trobot, twincal::calib::pipeline::Parametrisation::Hayati), Method::LM);
    let t = lm_speed(&tds, None, &topts, repeat)?;
    println!(
        "  LM, {} tracker points ({} residuals): {:8.2} ms median (target < 50 ms), {} iterations; one residual+Jacobian evaluation {:.3} ms -> LM = {:.1} evaluations; whole calibrate {:.1} ms; test RMSE {:.4} mm per coordinate",
        t.rows,
        t.residuals,
        t.lm_s * 1e3,
        t.iterations,
        t.evaluation_s * 1e3,
        t.lm_s / t.evaluation_s,
        t.whole_s * 1e3,
        t.test_rmse
    );

    accuracy_over_seeds(seeds, &opts, &gen)?;
    untuned_methods(&base, &robot, &spec)?;

    // 3. The full comparison over 30 seeds.
    if let Some(compare) = compare {
        let t0 = Instant::now();
        compare(&tmp.join(format!("s{}-400", 1000)))?;
        println!("  compare, 5 methods x 30 seeds: {:.1} s wall time", t0.elapsed().as_secs_f64());
    }
    real_data()?;
    drop(tmp_dir);
    Ok(())
}

/// 2. Accuracy over seeds: test RMSE against the noise floor, parameters against the truth.
#[allow(clippy::type_complexity)]
fn accuracy_over_seeds(
    seeds: u64,
    opts: &twincal::calib::pipeline::CalibOptions,
    gen: &(dyn Fn(u64, usize, usize) -> Result<(twincal::dataset::Dataset, twincal::calib::pipeline::TruthFile)> + Sync),
) -> Result<()> {
    use rayon::prelude::*;
    let rows: Vec<Result<(f64, usize, usize, f64)>> = (0..seeds)
        .into_par_iter()
        .map(|seed| {
            let (ds, truth) = gen(1000 + seed, 400, 100)?;
            let r = twincal::calib::pipeline::calibrate(&ds, Some(&truth), opts)?;
            let c = r.evaluation.truth_comparison.clone().ok_or_else(|| Error::Invalid("no truth comparison".into()))?;
            Ok((r.evaluation.metrics.test_after.map(|m| m.rmse).unwrap_or(f64::NAN) / truth.noise_std_mm, c.within_3_sigma, c.identifiable, c.max_abs_z))
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
    Ok(())
}

/// 2b. Untuned methods: a scenario whose spreads and noise differ from the defaults (0.8 mm,
/// 0.12°, 0.15° and 0.2 mm raw noise, 20 samples); priors come from the documented tolerances
/// and the noise from the data, never from the scenario.
fn untuned_methods(base: &Scenario, robot: &twincal::robot::Robot, spec: &twincal::calib::pipeline::ModelSpec) -> Result<()> {
    use rayon::prelude::*;
    use twincal::calib::pipeline::{CalibOptions, Method};
    let mut other = base.clone();
    other.geometry.origin_offset_std_mm = 0.8;
    other.geometry.origin_rotation_std_deg = 0.12;
    other.geometry.joint_zero_std_deg = 0.15;
    other.draw_wire.noise_std_mm = 0.2;
    other.draw_wire.samples = 20;
    let sets: Vec<(twincal::dataset::Dataset, f64)> = (0..5u64)
        .map(|i| {
            let mut s = other.clone();
            s.seed = 21 + i;
            let g = run_generate(&s, robot, &Silent)?;
            Ok((g.dataset, g.truth.noise_std_mm))
        })
        .collect::<Result<_>>()?;
    println!("  untuned methods on other spreads and noise (5 seeds, 400 poses, floor {:.4} mm): median test RMSE / floor, time per run", sets[0].1);
    for m in Method::family(twincal::calib::methods::Family::Baseline) {
        let t0 = Instant::now();
        let ratios: Vec<f64> = sets
            .par_iter()
            .map(|(ds, floor)| {
                let r = twincal::calib::pipeline::calibrate(ds, None, &CalibOptions::new(spec.clone(), m))?;
                Ok(r.evaluation.metrics.test_after.map(|t| t.rmse).unwrap_or(f64::NAN) / floor)
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
    Ok(())
}

/// 4. Real data: the HSR-RobotCali pool, when ../shared has it.
fn real_data() -> Result<()> {
    use twincal::calib::pipeline::{CalibOptions, Method, ModelSpec};
    let hsr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data/hsr-robotcali/hsr_robotcali_pool.csv");
    if !hsr.exists() {
        println!("  HSR-RobotCali: skipped, {} is absent", hsr.display());
        return Ok(());
    }
    let ds = twincal::dataset::Dataset::load(&hsr)?;
    let mut o = CalibOptions::new(ModelSpec::Generic, Method::LM);
    o.split.test_fraction = Some(0.2);
    let r = twincal::calib::pipeline::calibrate(&ds, None, &o)?;
    if let (Some(rep), Some(t), Some(tt)) = (&r.evaluation.repeatability, &r.evaluation.metrics.test_after, &r.evaluation.metrics.test_after_trimmed) {
        println!(
            "  HSR-RobotCali (generic6r, 80/20): held-out RMSE {:.4} mm, repeatability floor {:.4} mm, ratio {:.3} (target < 1.3); without the worst 1 % {:.3}; {:.1} s (bench real: the interleaved split over seeds)",
            t.rmse,
            rep.pooled_std,
            t.rmse / rep.pooled_std,
            tt.rmse / rep.pooled_std,
            r.provenance.wall_time_s
        );
    }
    Ok(())
}
