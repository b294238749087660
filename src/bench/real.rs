//! `twincal bench real`: the targets on real measured data (../shared/data, read at run time;
//! each dataset is skipped, saying so, when absent).
//!
//! * HSR-RobotCali, the generic model: every fifth row of the pool held out (interleaved with
//!   the training rows); per search seed the held-out RMSE without the worst 1 % over the data's
//!   floor, convergence and wall time; then `diagnose --model generic6r`, timed.
//! * RobotCali (the papers' IRB 120): `seeds` random 80/20 splits of LM, `dsade-gkan` and
//!   `pso-ekf-awnn`, with the outlier screen (default) and without it (`--outliers 0`, every
//!   row trains, as the papers' figures presumably do): test RMSE on every test row and on the
//!   rows that are not outliers, mean ± sd, beside the angle-resolution floor.

use crate::calib::psoekf::Ablation;
use crate::calib::run::{calibrate, CalibOptions, CalibResult, Method, ModelSpec};
use crate::dataset::{Dataset, Split};
use crate::error::Result;
use std::path::Path;
use std::time::Instant;

fn shared(rel: &str) -> Option<std::path::PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data").join(rel);
    if p.exists() {
        Some(p)
    } else {
        println!("  {rel}: skipped, {} is absent", p.display());
        None
    }
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    (m, (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt())
}

use crate::calib::stats::median;

/// `twincal bench real`.
pub fn bench_real(seeds: u64) -> Result<()> {
    println!("Real measured data (../shared/data)");
    if let Some(p) = shared("hsr-robotcali/hsr_robotcali_pool.csv") {
        let mut ds = Dataset::load(&p)?;
        for (i, r) in ds.rows.iter_mut().enumerate() {
            r.split = Some(if i % 5 == 4 { Split::Test } else { Split::Train });
        }
        println!("  HSR-RobotCali, generic6r, every 5th row held out (target: converged, <= 1.15 x the floor without the worst 1 %, < 10 s):");
        let mut times = Vec::new();
        for seed in 0..seeds {
            let mut o = CalibOptions::new(ModelSpec::Generic6r, Method::Lm);
            o.seed = seed;
            let t0 = Instant::now();
            let r = calibrate(&ds, None, &o)?;
            times.push(t0.elapsed().as_secs_f64());
            let floor = r.noise_floor.as_ref().map_or(f64::NAN, |f| f.total_mm);
            let (all, trimmed) = (r.metrics.test_after.map_or(f64::NAN, |t| t.rmse), r.metrics.test_after_trimmed.map_or(f64::NAN, |t| t.rmse));
            println!(
                "    seed {seed}: held-out {all:.4} mm, without the worst 1 % {trimmed:.4} mm = {:.3} x the floor {floor:.4} mm; converged {} ({} iterations), {:.1} s",
                trimmed / floor,
                r.converged,
                r.iterations,
                times.last().expect("just pushed")
            );
        }
        println!("    median wall time {:.1} s", median(&times));
        let ds = Dataset::load(&p)?;
        let t0 = Instant::now();
        let (d, _) = crate::diagnose::diagnose(&ds, &crate::diagnose::DiagnoseOptions::new(ModelSpec::Generic6r), &|_| {})?;
        println!(
            "  HSR-RobotCali diagnose --model generic6r: {} ; final held-out {:.4} mm = {:.2} x the floor; {:.1} s (target < 30 s)",
            d.verdict,
            d.final_heldout_rmse_mm,
            d.final_heldout_rmse_mm / d.noise_floor_mm,
            t0.elapsed().as_secs_f64()
        );
    }
    if let Some(p) = shared("robotcali-irb120/robotcali_pool.csv") {
        let ds = Dataset::load(&p)?;
        println!("  RobotCali IRB 120, hayati, {seeds} random 80/20 splits: test RMSE mean ± sd (mm), every test row | rows that are not outliers");
        println!("    (the papers: LM about 1.2, Evo-NPH 0.62, PSO-EKF-AWNN 0.73 mm, splits unpublished)");
        let mut floor = f64::NAN;
        for method in [Method::Lm, Method::DsadeGkan, Method::PsoEkfAwnn(Ablation::Full)] {
            for k in [crate::calib::run::DEFAULT_OUTLIER_K, 0.0] {
                let mut runs: Vec<CalibResult> = Vec::new();
                let t0 = Instant::now();
                for seed in 0..seeds {
                    let mut o = CalibOptions::new(ModelSpec::parse("irb120", "hayati")?, method);
                    o.test_fraction = Some(0.2);
                    o.seed = seed;
                    o.outlier_k = k;
                    runs.push(calibrate(&ds, None, &o)?);
                }
                if floor.is_nan() {
                    floor = runs[0].noise_floor.as_ref().map_or(f64::NAN, |f| f.total_mm);
                }
                let all: Vec<f64> = runs.iter().map(|r| r.metrics.test_after.map_or(f64::NAN, |t| t.rmse)).collect();
                let inl: Vec<f64> = runs.iter().map(|r| r.metrics.test_after_inliers.map_or(f64::NAN, |t| t.rmse)).collect();
                let (ma, sa) = mean_sd(&all);
                let conv = runs.iter().filter(|r| r.converged).count();
                let label = if k > 0.0 { "screened" } else { "every row" };
                let inliers = if k > 0.0 {
                    let (mi, si) = mean_sd(&inl);
                    format!("{mi:.3} ± {si:.3}")
                } else {
                    "-".into()
                };
                println!(
                    "    {:<13} {label:<10} {ma:.3} ± {sa:.3} | {inliers}; converged {conv}/{seeds}; {:.1} s per run",
                    method.name(),
                    t0.elapsed().as_secs_f64() / seeds as f64
                );
            }
        }
        println!("    the data's floor (0.1 deg angle logging through the screened LM model, first split): {floor:.3} mm");
    }
    Ok(())
}
