//! `twincal bench real`: the targets on real measured data (../shared/data, read at run time;
//! each dataset is skipped, saying so, when absent).
//!
//! * HSR-RobotCali, the generic model: every fifth row of the pool held out (interleaved with
//!   the training rows); per search seed the held-out RMSE without the worst 1 % over the data's
//!   floor, convergence and wall time; then `diagnose --model generic6r`, timed.
//! * The tracker files without their URDF ([`crate::bench::generic`]).
//! * RobotCali (the papers' IRB 120): `seeds` random 80/20 splits of LM, `dsade-gkan` and
//!   `pso-ekf-awnn`, with the outlier screen (default) and without it (`--outliers 0`, every
//!   row trains, as the papers' figures presumably do): test RMSE on every test row and on the
//!   rows that are not outliers, mean ± sd, beside the angle-resolution floor.
//!
//! `twincal bench diagnose-ur10` ([`bench_diagnose_ur10`]) times `diagnose` on the UR10's
//! 11 911-row series a against its 60 s target, and rows against seconds of the generic arm's
//! diagnosis on its first 1 000 to 10 000 rows.

use std::path::Path;
use std::time::Instant;
use twincal::calib::pipeline::{calibrate, CalibOptions, CalibResult, Method, ModelSpec};
use twincal::dataset::{Dataset, Split};
use twincal::error::Result;

fn shared(rel: &str) -> Option<std::path::PathBuf> {
    shared_in("data", rel)
}

/// `../shared/FOLDER/rel` when it exists; else None, saying it is skipped.
fn shared_in(folder: &str, rel: &str) -> Option<std::path::PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared").join(folder).join(rel);
    if p.exists() {
        Some(p)
    } else {
        println!("  {rel}: skipped, {} is absent", p.display());
        None
    }
}

/// The diagnosis of series a must take less than this (s, median wall time).
pub const DIAGNOSE_UR10_TARGET_S: f64 = 60.0;

/// CSV text with its data lines in ascending order of column `column` (stable: equal values keep
/// their order; a value that is not a number sorts last). The header stays first; line ends
/// become `\n`.
pub fn sorted_by_column(text: &str, column: &str) -> Option<String> {
    let mut lines = text.lines();
    let header = lines.next()?;
    let k = header.split(',').position(|c| c.trim() == column)?;
    let key = |l: &str| l.split(',').nth(k).and_then(|v| v.trim().parse::<f64>().ok()).unwrap_or(f64::NAN);
    let mut rows: Vec<(f64, &str)> = lines.filter(|l| !l.trim().is_empty()).map(|l| (key(l), l)).collect();
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out = String::with_capacity(text.len());
    for l in std::iter::once(header).chain(rows.into_iter().map(|r| r.1)) {
        out.push_str(l);
        out.push('\n');
    }
    Some(out)
}

/// `twincal bench diagnose-ur10`: `diagnose --model ur_description/ur10_robot.urdf` on the
/// UR10's series a (11 911 tracker rows, 35 733 residuals; ../shared/data/ipa-ur10, sorted by
/// `t` in memory since its last rows are not in time order), `runs` times: the median wall time
/// against [`DIAGNOSE_UR10_TARGET_S`], and what it named.
pub fn bench_diagnose_ur10(runs: usize) -> Result<()> {
    use twincal::diagnose::{diagnose, DiagnoseOptions};
    println!("diagnose on the UR10's series a (../shared/data/ipa-ur10, sorted by t; the probe's position x, y, z, as --measurement point reads it)");
    let (Some(data), Some(urdf)) = (shared("ipa-ur10/ur10_series_a.csv"), shared_in("reference", "ur_description/ur10_robot.urdf")) else {
        return Ok(());
    };
    let text = std::fs::read_to_string(&data).map_err(|e| twincal::error::Error::io(&data, e))?;
    let sorted = sorted_by_column(&text, "t").ok_or_else(|| twincal::error::Error::data(data.display(), "no header with a t column"))?;
    // The position table of the README (the file's orientation columns are a pose's).
    let point = twincal::dataset::ReadOptions { measurement: Some(twincal::measurement::Measurement::Point), ..Default::default() };
    let ds = Dataset::from_csv_reader_with(sorted.as_bytes(), &format!("{} (sorted by t)", data.display()), &point)?;
    let opts = DiagnoseOptions::new(ModelSpec::nominal(twincal::robot::Robot::from_urdf_file(&urdf)?, twincal::calib::pipeline::Parametrisation::Hayati));
    let mut times = Vec::new();
    let mut found: Vec<String> = Vec::new();
    for run in 1..=runs {
        let t0 = Instant::now();
        let (d, _) = diagnose(&ds, &opts, &|_| {})?;
        times.push(t0.elapsed().as_secs_f64());
        let causes: Vec<String> =
            d.causes.iter().map(|c| format!("{}: {} {:.2} ± {:.2} {}", c.label(), c.quantity, c.magnitude, c.uncertainty, c.unit)).collect();
        let line = format!(
            "{}; held-out RMSE {:.4} -> {:.4} mm",
            if causes.is_empty() { d.verdict.clone() } else { causes.join(" + ") },
            d.baseline.heldout_rmse_mm,
            d.final_heldout_rmse_mm
        );
        println!("    run {run}: {:.1} s, {line}", times.last().expect("just pushed"));
        found.push(line);
    }
    let med = median(&times);
    let same = found.windows(2).all(|w| w[0] == w[1]);
    println!(
        "  {} rows ({} residuals), {} threads: {med:.1} s median of {runs} (target < {DIAGNOSE_UR10_TARGET_S:.0} s: {}); found {}{}",
        ds.rows.len(),
        ds.rows.iter().map(|r| r.reading_mm.len()).sum::<usize>(),
        rayon::current_num_threads(),
        if med < DIAGNOSE_UR10_TARGET_S { "met" } else { "missed" },
        found.first().map_or("nothing", String::as_str),
        if same { "" } else { " (the runs did not all find the same: see above)" }
    );
    growth(&sorted, &data.display().to_string(), runs)
}

/// Rows of series a (sorted by t) diagnosed by [`growth`], and the targets of 2 000 and 10 000.
pub const GROWTH_ROWS: [usize; 4] = [1_000, 2_000, 5_000, 10_000];
/// See [`GROWTH_ROWS`]: the target for 2 000 and for 10 000 rows, s.
pub const GROWTH_TARGETS_S: [(usize, f64); 2] = [(2_000, 20.0), (10_000, 90.0)];

/// Rows against seconds: `diagnose --model generic6r` as the command runs it (the set-up's
/// stations searched first) on the first [`GROWTH_ROWS`] rows of series a in time (`sorted`),
/// read as the probe's 6-D poses; the median of `runs` each, seconds per 1 000 rows and the
/// growth exponent between successive sizes (1: linear).
fn growth(sorted: &str, source: &str, runs: usize) -> Result<()> {
    println!("  rows against seconds: diagnose --model generic6r on the first rows of series a in time, 6-D poses, as the command runs it");
    let pose = Dataset::from_csv_reader_with(sorted.as_bytes(), &format!("{source} (sorted by t)"), &Default::default())?;
    let request = twincal::requests::DiagnoseRequest::default();
    let opts = twincal::diagnose::DiagnoseOptions::new(ModelSpec::Generic);
    let mut points: Vec<(usize, f64)> = Vec::new();
    for n in GROWTH_ROWS.into_iter().filter(|n| *n <= pose.rows.len()) {
        let part = Dataset { rows: pose.rows[..n].to_vec(), source: format!("{source} (first {n} rows in time)") };
        let mut times = Vec::new();
        let mut verdict = String::new();
        for _ in 0..runs {
            let t0 = Instant::now();
            let d = twincal::jobs::diagnose_loaded(&request, (opts.clone(), Default::default()), part.clone(), &|_| {})?;
            times.push(t0.elapsed().as_secs_f64());
            verdict = d.report.verdict;
        }
        let med = median(&times);
        let exponent =
            points.last().map_or(String::new(), |&(m, t)| format!(", growth exponent {:.2} from {m} rows", (med / t).ln() / (n as f64 / m as f64).ln()));
        let target = GROWTH_TARGETS_S
            .iter()
            .find(|(r, _)| *r == n)
            .map_or(String::new(), |(_, s)| format!(" (target < {s:.0} s: {})", if med < *s { "met" } else { "missed" }));
        println!("    {n:>6} rows: {med:.1} s median of {runs}{target}, {:.2} s per 1 000 rows{exponent}; {verdict}", 1000.0 * med / n as f64);
        points.push((n, med));
    }
    Ok(())
}

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let n = v.len().max(1) as f64;
    let m = v.iter().sum::<f64>() / n;
    (m, (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0).max(1.0)).sqrt())
}

use twincal::stats::median;

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
            let mut o = CalibOptions::new(ModelSpec::Generic, Method::LM);
            o.seed = seed;
            let t0 = Instant::now();
            let r = calibrate(&ds, None, &o)?;
            times.push(t0.elapsed().as_secs_f64());
            let floor = r.evaluation.noise_floor.as_ref().map_or(f64::NAN, |f| f.total_mm);
            let (all, trimmed) =
                (r.evaluation.metrics.test_after.map_or(f64::NAN, |t| t.rmse), r.evaluation.metrics.test_after_trimmed.map_or(f64::NAN, |t| t.rmse));
            println!(
                "    seed {seed}: held-out {all:.4} mm, without the worst 1 % {trimmed:.4} mm = {:.3} x the floor {floor:.4} mm; converged {} ({} iterations), {:.1} s",
                trimmed / floor,
                r.solve.converged,
                r.solve.iterations,
                times.last().expect("just pushed")
            );
        }
        println!("    median wall time {:.1} s", median(&times));
        let ds = Dataset::load(&p)?;
        let t0 = Instant::now();
        let (d, _) = twincal::diagnose::diagnose(&ds, &twincal::diagnose::DiagnoseOptions::new(ModelSpec::Generic), &|_| {})?;
        println!(
            "  HSR-RobotCali diagnose --model generic6r: {} ; final held-out {:.4} mm = {:.2} x the floor; {:.1} s (target < 30 s)",
            d.verdict,
            d.final_heldout_rmse_mm,
            d.final_heldout_rmse_mm / d.noise_floor_mm,
            t0.elapsed().as_secs_f64()
        );
    }
    crate::bench::generic::bench_generic_trackers(seeds, &shared_in)?;
    if let Some(p) = shared("robotcali-irb120/robotcali_pool.csv") {
        let ds = Dataset::load(&p)?;
        println!("  RobotCali IRB 120, hayati, {seeds} random 80/20 splits: test RMSE mean ± sd (mm), every test row | rows that are not outliers");
        println!("    (the papers: LM about 1.2, Evo-NPH 0.62, PSO-EKF-AWNN 0.73 mm, splits unpublished)");
        let mut floor = f64::NAN;
        for method in [Method::LM, Method::DSADE_GKAN, Method::PSO_EKF_AWNN] {
            use twincal::calib::fit::noise_model::NoiseChoice;
            for (k, noise) in [
                (twincal::calib::pipeline::DEFAULT_OUTLIER_K, NoiseChoice::Auto),
                (twincal::calib::pipeline::DEFAULT_OUTLIER_K, NoiseChoice::Off),
                (0.0, NoiseChoice::Auto),
            ] {
                let mut runs: Vec<CalibResult> = Vec::new();
                let t0 = Instant::now();
                for seed in 0..seeds {
                    let mut o =
                        CalibOptions::new(ModelSpec::nominal(twincal::robot::Robot::irb120(), twincal::calib::pipeline::Parametrisation::Hayati), method);
                    o.split.test_fraction = Some(0.2);
                    // The papers' protocol: random rows (their splits are not published).
                    o.split.by = twincal::calib::pipeline::SplitBy::Rows;
                    o.seed = seed;
                    o.screen.outlier_k = k;
                    o.floor.noise_model = noise;
                    runs.push(calibrate(&ds, None, &o)?);
                }
                if floor.is_nan() {
                    floor = runs[0].evaluation.noise_floor.as_ref().map_or(f64::NAN, |f| f.total_mm);
                }
                let all: Vec<f64> = runs.iter().map(|r| r.evaluation.metrics.test_after.map_or(f64::NAN, |t| t.rmse)).collect();
                let inl: Vec<f64> = runs.iter().map(|r| r.evaluation.metrics.test_after_inliers.map_or(f64::NAN, |t| t.rmse)).collect();
                let (ma, sa) = mean_sd(&all);
                let conv = runs.iter().filter(|r| r.solve.converged).count();
                let label = match (k > 0.0, noise) {
                    (true, NoiseChoice::Auto) => "screened",
                    (true, NoiseChoice::Off) => "screened, --noise-model off",
                    (false, _) => "every row",
                };
                let inliers = if k > 0.0 {
                    let (mi, si) = mean_sd(&inl);
                    format!("{mi:.3} ± {si:.3}")
                } else {
                    "-".into()
                };
                println!(
                    "    {:<13} {label:<27} {ma:.3} ± {sa:.3} | {inliers}; converged {conv}/{seeds}; {:.1} s per run",
                    method.name(),
                    t0.elapsed().as_secs_f64() / seeds as f64
                );
            }
        }
        println!("    the data's floor (0.1 deg angle logging through the screened LM model, first split): {floor:.3} mm");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sorting_by_a_column_keeps_the_header_and_the_order_of_ties() {
        let text = "q1,t,x\r\n1,20.0,a\r\n2,5,b\r\n3,,c\r\n4,5.0,d\r\n\r\n5,-1,e\r\n";
        assert_eq!(sorted_by_column(text, "t").unwrap(), "q1,t,x\n5,-1,e\n2,5,b\n4,5.0,d\n1,20.0,a\n3,,c\n");
        assert_eq!(sorted_by_column(text, "temp"), None);
        assert_eq!(sorted_by_column("", "t"), None);
    }
}
